"""Newton's method for the frustum whose image has a given bounding box, as one compiled loop
(:func:`percept.perception.footprint.fit_frustum_box`: the cylinder fit of every anchor's
sensory experience in every frame the camera moved, and the refit of a frustum's shape).

The same steps as :func:`percept.perception.footprint._newton` with four unknowns and the box's
four edges: each step measures the frustum at its parameters and at each one moved by ``step``
(the numeric Jacobian) and solves the 4x4 system by Gaussian elimination with partial pivoting
(LAPACK's LU, in a loop); a system without a pivot takes numpy's least-squares step. In Python
a step was some 30 numpy calls (about 60 µs); here the whole fit is one call.
"""

from __future__ import annotations

import numpy as np

from percept.perception.kernels import jit
from percept.perception.kernels.features.images import outline_images
from percept.perception.kernels.features.solids import frusta

_EPS = 2.220446049250313e-16  # float64's machine epsilon


@jit
def solve4(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with ``a @ x = b`` for a square ``a`` (n, n) by LU with partial pivoting; the
    least-squares (least-norm) x when ``a`` has no pivot in some column."""
    n = b.shape[0]
    m, x = a.copy(), b.copy()
    for col in range(n):
        pivot = col
        for row in range(col + 1, n):
            if abs(m[row, col]) > abs(m[pivot, col]):
                pivot = row
        if m[pivot, col] == 0.0:
            return np.linalg.lstsq(a, b, rcond=_EPS * n)[0]  # numpy's default rcond
        if pivot != col:
            for j in range(n):
                m[col, j], m[pivot, j] = m[pivot, j], m[col, j]
            x[col], x[pivot] = x[pivot], x[col]
        for row in range(col + 1, n):
            f = m[row, col] / m[col, col]
            for j in range(col, n):
                m[row, j] -= f * m[col, j]
            x[row] -= f * x[col]
    for row in range(n - 1, -1, -1):
        s = x[row]
        for j in range(row + 1, n):
            s -= m[row, j] * x[j]
        x[row] = s / m[row, row]
    return x


@jit
def frustum_box_newton(
    edges: np.ndarray,
    k: float,
    start: np.ndarray,
    rim: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    K: np.ndarray,
    iterations: int,
    step: float,
    tolerance: float,
    settled: float,
) -> tuple[bool, np.ndarray]:
    """Footprint centre x, y, bottom diameter and height (4,) of the upright frustum of
    top-to-bottom ratio ``k`` whose image through the camera (``R``, ``t``, ``K``: as
    :func:`outline_images`) spans ``edges`` (left, right, top, bottom), from ``start``; its rims
    drawn with the points of ``rim``. Settled when every edge is within ``tolerance`` pixels or a
    step moves no parameter by ``settled``; False when a step leaves the frusta of positive size
    in front of the camera or ``iterations`` steps do not settle."""
    p = start.copy()
    params = np.empty((5, 5))
    jacobian = np.empty((4, 4))
    residual = np.empty(4)
    for _ in range(iterations):
        for row in range(5):
            for j in range(4):
                params[row, j] = p[j]
            params[row, 4] = k
            if row > 0:
                params[row, row - 1] = p[row - 1] + step
        measured = outline_images(frusta(params, rim), R, t, K, False)
        for row in range(5):
            for j in range(4):
                if not np.isfinite(measured[row, j]):
                    return False, p
        worst = 0.0
        for j in range(4):
            residual[j] = measured[0, j] - edges[j]
            worst = max(worst, abs(residual[j]))
        if worst < tolerance:
            return True, p
        for i in range(4):  # d edge i / d parameter j
            for j in range(4):
                jacobian[i, j] = (measured[j + 1, i] - measured[0, i]) / step
        delta = solve4(jacobian, residual)
        largest = 0.0
        for j in range(4):
            p[j] -= delta[j]
            largest = max(largest, abs(delta[j]))
        if p[2] <= 0 or p[3] <= 0:
            return False, p
        if largest < settled:
            return True, p
    return False, p
