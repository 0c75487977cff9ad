"""The photometric fit of :mod:`.photometric` in one compiled pass.

The samples are taken from the frame on a sparse grid, where no mask excludes them. When the
photometry fitted before still holds on them (it keeps about as many of them as it kept when
fitted, and what it keeps departs from it by less than ``hold`` grey levels on average, as a
whole or along the channel's values), it is kept: that costs one pass over the samples, while
the fit's nine medians cost some twenty. Otherwise per channel ``observed - C = gain (expected -
C) + offset``, started from the median ratio of Y and trimmed of outliers twice before each
least-squares fit; the module of the light says why.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.light.photometry.order_kernels import median

TRIM = 3.0
"""Residuals beyond this many robust deviations (1.4826 MAD, at least 1) are outliers."""
SHARE_DROP = 0.05
"""The photometry fitted before no longer holds when it keeps this much less of the samples
than it kept when fitted (something entered the samples, or the light changed beyond the trim).
The share kept of 600 samples varies by about a hundredth from frame to frame."""


@jit
def fit_photometry(
    ycc: np.ndarray,
    expected: np.ndarray,
    excluded: np.ndarray,
    previous: np.ndarray,
    step: int,
    current: np.ndarray,
    min_share: float,
    min_inliers: float,
    centre: np.ndarray,
    min_spread: float,
    hold: float,
) -> tuple[np.ndarray, int]:
    """The photometry mapping ``expected`` to ``ycc`` (uint8 (H, W, 3)) around ``centre``,
    fitted on every ``step``-th pixel of every ``step``-th row that neither ``excluded`` (bool
    (H, W)) nor ``previous`` (uint8 (H, W), not 0) marks. ``expected`` (float32 (H', W', 3))
    holds the expected values of that grid's pixels only (``H' = ceil(H / step)``): a copy of
    the model's mean on the grid, which stays in the cache, where the samples of the whole mean
    (300 KB at 176x144, read from memory each frame) cost two thirds of the fit.

    Photometries are (4, 3) arrays: gain, offset and the robust deviation of the residuals per
    channel, then the share of the samples the fit kept (first column); ``current`` is the one
    in use (deviation 0: none fitted). Returns ``(photometry, inliers)``: ``inliers`` -1 keeps
    ``current`` (it still holds, fewer than ``min_share`` of the grid's pixels were samples, or
    the fit kept fewer than ``min_inliers`` of them), 0 the identity (a failed fit)."""
    grid = expected.shape[0] * expected.shape[1]
    y = np.empty((3, grid))
    x = np.empty((3, grid))
    n = 0
    for i in range(expected.shape[0]):
        v = i * step
        for j in range(expected.shape[1]):
            u = j * step
            if excluded[v, u] or previous[v, u] != 0:
                continue
            for c in range(3):
                y[c, n] = ycc[v, u, c] - centre[c]
                x[c, n] = expected[i, j, c] - centre[c]
            n += 1
    if n < min_share * grid:
        return current, -1
    if current[2, 0] > 0.0 and _holds(x, y, n, current, min_spread, hold):
        return current, -1
    fitted, inliers = _fit(x, y, n, min_spread)
    if inliers and inliers < min_inliers * n:
        return current, -1
    return fitted, inliers


@jit
def _holds(
    x: np.ndarray, y: np.ndarray, n: int, current: np.ndarray, min_spread: float, hold: float
) -> bool:
    """Whether ``current`` keeps at least its share of the ``n`` samples (less
    :data:`SHARE_DROP`) and the residuals of those it keeps average within ``hold`` of 0, and
    change by less than ``hold`` over a deviation of the channel's values (a gain off)."""
    sums = np.zeros((3, 4))  # per channel: residual, value, value squared, their product
    kept = 0
    for i in range(n):
        inside = True
        for c in range(3):
            r = y[c, i] - current[0, c] * x[c, i] - current[1, c]
            if not abs(r) <= TRIM * current[2, c]:
                inside = False
                break
        if not inside:
            continue
        kept += 1
        for c in range(3):
            r = y[c, i] - current[0, c] * x[c, i] - current[1, c]
            sums[c, 0] += r
            sums[c, 1] += x[c, i]
            sums[c, 2] += x[c, i] * x[c, i]
            sums[c, 3] += x[c, i] * r
    if kept < 8 or kept < (current[3, 0] - SHARE_DROP) * n:
        return False
    for c in range(3):
        mr, mx = sums[c, 0] / kept, sums[c, 1] / kept
        if abs(mr) > hold:
            return False
        var = sums[c, 2] / kept - mx * mx
        if var >= min_spread**2 and abs(sums[c, 3] / kept - mx * mr) > hold * np.sqrt(var):
            return False
    return True


@jit
def _fit(x: np.ndarray, y: np.ndarray, n: int, min_spread: float) -> tuple[np.ndarray, int]:
    """The photometry (see :func:`fit_photometry`) of the first ``n`` samples of ``x`` and
    ``y`` (3, n or more; trimmed in place); 0 inliers and the identity when it failed."""
    total = n
    identity = np.zeros((4, 3))
    identity[0] = 1.0
    if n < 8:
        return identity, 0
    # Loops over scratch arrays rather than array expressions: the masks, temporaries and
    # column selections cost as much as the nine medians (the fit's real work) at 600 samples.
    work = np.empty(n)
    bright = 0
    for i in range(n):
        if x[0, i] >= 16.0:
            work[bright] = y[0, i] / x[0, i]
            bright += 1
    ratio = median(work, bright) if bright >= 8 else 1.0
    gain = np.full(3, min(max(ratio, 0.05), 20.0))
    offset = np.zeros(3)
    for c in range(1, 3):
        for i in range(n):
            work[i] = y[c, i] - gain[c] * x[c, i]
        offset[c] = median(work, n)
    residual = np.empty((3, n))
    scale = np.empty(3)
    keep = np.empty(n, np.bool_)
    for _ in range(2):
        keep[:n] = True
        for c in range(3):
            for i in range(n):
                residual[c, i] = abs(y[c, i] - gain[c] * x[c, i] - offset[c])
                work[i] = residual[c, i]
            scale[c] = max(1.4826 * median(work, n), 1.0)
            for i in range(n):
                if not residual[c, i] <= TRIM * scale[c]:
                    keep[i] = False
        kept = 0
        for i in range(n):
            if keep[i]:
                for c in range(3):
                    x[c, kept] = x[c, i]
                    y[c, kept] = y[c, i]
                kept += 1
        if kept < 8:
            return identity, 0
        n = kept
        gain, offset = _least_squares(x[:, :n], y[:, :n], min_spread)
    fitted = np.zeros((4, 3))
    fitted[0, :] = gain
    fitted[1, :] = offset
    fitted[2, :] = scale
    fitted[3, 0] = n / total
    return fitted, n


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


@jit
def affine_map(gain: np.ndarray, offset: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The 3x4 affine map (float64) of a frame's values to the calibration's light of a
    photometry of ``gain`` and ``offset`` per channel (float64 (3,)): per channel ``c``,
    ``expected = (observed - centre - offset) / gain + centre``, as ``cv2.transform`` takes it."""
    matrix = np.zeros((3, 4))
    for c in range(3):
        matrix[c, c] = 1.0 / gain[c]
        matrix[c, 3] = centre[c] - (centre[c] + offset[c]) / gain[c]
    return matrix
