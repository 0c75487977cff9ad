"""The constant-velocity box filters' prediction and correction (:mod:`percept.perception.kalman`)
in one compiled loop over the boxes each, in place.

Each box's covariance is the three numbers ``a, b, c`` of ``[[a I, b I], [b I, c I]]``; the
arithmetic is that of the module of the filters, operation for operation, so the states come
out as the array expressions gave them (which the tests check against filterpy).
"""

from __future__ import annotations

import numpy as np

from percept.perception.kernels import jit


@jit
def predict(x: np.ndarray, cov: np.ndarray, q: float, min_size: float) -> None:
    """``s = A s``, ``P = A P A^T + Q`` for every row of ``x`` (n, 8) and ``cov`` (n, 3); a
    width or height below ``min_size`` becomes ``min_size`` (as ``np.maximum``: NaN stays)."""
    for i in range(x.shape[0]):
        for k in range(4):
            x[i, k] += x[i, k + 4]
        for k in range(2, 4):
            if x[i, k] < min_size:
                x[i, k] = min_size
        a, b, c = cov[i, 0], cov[i, 1], cov[i, 2]
        cov[i, 0] = a + 2 * b + c + q
        cov[i, 1] = b + c
        cov[i, 2] = c + q


@jit
def update(x: np.ndarray, cov: np.ndarray, rows: np.ndarray, z: np.ndarray, r: float) -> None:
    """Correct the filters ``rows`` of ``x`` (n, 8) and ``cov`` (n, 3) with measurements ``z``
    (len(rows), 4) of noise ``r``: gain ``K = [a/s I; b/s I]`` with ``s = a + r``."""
    for k in range(rows.shape[0]):
        i = rows[k]
        a, b, c = cov[i, 0], cov[i, 1], cov[i, 2]
        s = a + r
        gain_value, gain_rate = a / s, b / s
        for j in range(4):
            innovation = z[k, j] - x[i, j]
            x[i, j] += gain_value * innovation
            x[i, j + 4] += gain_rate * innovation
        cov[i, 2] = c - b * gain_rate
        shrink = r / s
        cov[i, 0] = a * shrink
        cov[i, 1] = b * shrink


@jit
def boxes(x: np.ndarray) -> np.ndarray:
    """(n, 4) boxes (left, top, width, height) of the states ``x`` (n, 8) whose first four are
    the centre, width and height."""
    out = np.empty((x.shape[0], 4))
    for i in range(x.shape[0]):
        out[i, 0] = x[i, 0] - x[i, 2] / 2
        out[i, 1] = x[i, 1] - x[i, 3] / 2
        out[i, 2] = x[i, 2]
        out[i, 3] = x[i, 3]
    return out
