"""The colour models' kernels: a pixel's bins in each factor of a model, and the model of a set
of pixels (:class:`percept.perception.colour.Coding` says what the factors are)."""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def codes(
    y: int, cr: int, cb: int, shift: int, m: int, joint: bool
) -> tuple[np.intp, np.intp, np.intp]:
    """A pixel's bin in each factor: ``(h(Y), h(Cr), h(Cb))``, or with ``joint`` chroma
    ``(h(Y), h(Cr) m + h(Cb), 0)`` (two factors; the third is not counted)."""
    b_y, b_cr, b_cb = np.intp(y) >> shift, np.intp(cr) >> shift, np.intp(cb) >> shift
    if joint:
        return b_y, b_cr * m + b_cb, np.intp(0)
    return b_y, b_cr, b_cb


@jit
def histograms_of(ycc: np.ndarray, shift: int, m: int, joint: bool) -> np.ndarray:
    """The normalised colour model (factors, bins) of pixels ``ycc`` (k, 3) uint8, k > 0."""
    factors, width = (2, m * m) if joint else (3, m)
    out = np.zeros((factors, width))
    for i in range(ycc.shape[0]):
        b0, b1, b2 = codes(ycc[i, 0], ycc[i, 1], ycc[i, 2], shift, m, joint)
        out[0, b0] += 1.0
        out[1, b1] += 1.0
        if not joint:
            out[2, b2] += 1.0
    return out / ycc.shape[0]
