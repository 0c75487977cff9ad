"""The constant-velocity box filters' prediction and correction
(:mod:`percept.perception.tracking.kalman`) in one compiled loop over the boxes each, in place.

Each box's covariance is the three numbers ``a, b, c`` of ``[[a I, b I], [b I, c I]]``; the
arithmetic is that of the module of the filters, operation for operation, so the states come
out as the array expressions gave them (which the tests check against filterpy).
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


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


@jit
def warp(x: np.ndarray, H: np.ndarray, q: np.ndarray) -> None:
    """Every state of ``x`` (n, 8) carried into the view that the homography ``H`` (3x3, old
    pixels to new) maps to, as :meth:`percept.perception.tracking.kalman.BoxFilters.warp` describes,
    ``q`` (n, 3) the homogeneous places where ``H`` takes the feet (a matrix product, which
    BLAS sums in its own order); a state whose foot lies behind the camera (q_z <= 1e-9) is
    left as it is."""
    for i in range(x.shape[0]):
        qz = q[i, 2]
        if not qz > 1e-9:
            continue
        mx, my = q[i, 0] / qz, q[i, 1] / qz
        # d(q_xy / q_z) / d(u, v) = (H[:2, :2] - moved (x) H[2, :2]) / q_z
        j00, j01 = (H[0, 0] - mx * H[2, 0]) / qz, (H[0, 1] - mx * H[2, 1]) / qz
        j10, j11 = (H[1, 0] - my * H[2, 0]) / qz, (H[1, 1] - my * H[2, 1]) / qz
        # How long the image's x and y axes become.
        sx, sy = np.sqrt(j00 * j00 + j10 * j10), np.sqrt(j01 * j01 + j11 * j11)
        x[i, 2] *= sx
        x[i, 3] *= sy
        x[i, 6] *= sx
        x[i, 7] *= sy
        rx, ry = x[i, 4], x[i, 5]
        x[i, 4] = j00 * rx + j01 * ry
        x[i, 5] = j10 * rx + j11 * ry
        x[i, 0] = mx
        x[i, 1] = my - x[i, 3] / 2
