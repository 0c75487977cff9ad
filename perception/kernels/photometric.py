"""The photometric fit of :mod:`percept.perception.light.photometric` in one compiled pass.

Per channel ``observed - C = gain (expected - C) + offset``, started from the median ratio of Y
and trimmed of outliers twice before each least-squares fit; the module of the light says why.
"""

from __future__ import annotations

import numpy as np

from percept.perception.kernels import jit

TRIM = 3.0
"""Residuals beyond this many robust deviations (1.4826 MAD, at least 1) are outliers."""


@jit
def fit_photometry(
    observed: np.ndarray, expected: np.ndarray, centre: np.ndarray, min_spread: float
) -> tuple[np.ndarray, np.ndarray, int]:
    """``(gain (3,), offset (3,), inliers)`` mapping ``expected`` to ``observed`` ((n, 3) each,
    any numeric type) around ``centre``; ``inliers`` 0 when the fit failed (the identity)."""
    n = observed.shape[0]
    y = np.empty((3, n))
    x = np.empty((3, n))
    for i in range(n):
        for c in range(3):
            y[c, i] = observed[i, c] - centre[c]
            x[c, i] = expected[i, c] - centre[c]
    identity = (np.ones(3), np.zeros(3), 0)
    if n < 8:
        return identity
    # Loops over scratch arrays rather than array expressions: the masks, temporaries and
    # column selections cost as much as the nine medians (the fit's real work) at 600 samples.
    work = np.empty(n)
    bright = 0
    for i in range(n):
        if x[0, i] >= 16.0:
            work[bright] = y[0, i] / x[0, i]
            bright += 1
    ratio = np.median(work[:bright]) if bright >= 8 else 1.0
    gain = np.full(3, min(max(ratio, 0.05), 20.0))
    offset = np.zeros(3)
    for c in range(1, 3):
        for i in range(n):
            work[i] = y[c, i] - gain[c] * x[c, i]
        offset[c] = np.median(work)
    residual = np.empty((3, n))
    keep = np.empty(n, np.bool_)
    for _ in range(2):
        keep[:n] = True
        for c in range(3):
            for i in range(n):
                residual[c, i] = abs(y[c, i] - gain[c] * x[c, i] - offset[c])
            scale = max(1.4826 * np.median(residual[c, :n]), 1.0)
            for i in range(n):
                if not residual[c, i] <= TRIM * scale:
                    keep[i] = False
        kept = 0
        for i in range(n):
            if keep[i]:
                for c in range(3):
                    x[c, kept] = x[c, i]
                    y[c, kept] = y[c, i]
                kept += 1
        if kept < 8:
            return identity
        n = kept
        gain, offset = _least_squares(x[:, :n], y[:, :n], min_spread)
    return gain, offset, n


@jit
def _least_squares(x: np.ndarray, y: np.ndarray, min_spread: float) -> tuple[np.ndarray, ...]:
    """Per channel gain and offset of ``y = gain x + offset``; a channel whose ``x`` spreads
    less than ``min_spread`` takes the gain of Y through the origin (and Y no offset)."""
    n = x.shape[1]
    gain, offset = np.empty(3), np.empty(3)
    # plain loops: the vector products went through BLAS calls and temporaries, several times
    # the cost of the sums at a few hundred samples
    xy = xx = 0.0
    for i in range(n):
        xy += x[0, i] * y[0, i]
        xx += x[0, i] * x[0, i]
    pure = xy / max(xx, 1e-9)
    for c in range(3):
        sx = sy = 0.0
        for i in range(n):
            sx += x[c, i]
            sy += y[c, i]
        mx, my = sx / n, sy / n
        var = cov = 0.0
        for i in range(n):
            d = x[c, i] - mx
            var += d * d
            cov += d * y[c, i]
        var, cov = var / n, cov / n
        spread = var >= min_spread**2
        g = cov / max(var, 1e-9) if spread else pure
        gain[c] = min(max(g, 0.05), 20.0)  # a black or blinding frame must not divide by zero
        offset[c] = my - gain[c] * mx
        if c == 0 and not spread:
            offset[c] = 0.0
    return gain, offset
