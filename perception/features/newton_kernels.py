"""Newton's method for the frustum whose image has a given bounding box, as one compiled loop
(:func:`percept.perception.features.footprint.fit_frustum_box`: the cylinder fit of every anchor's
sensory experience in every frame the camera moved, and the refit of a frustum's shape).

The same steps as :func:`percept.perception.features.footprint._newton` with four unknowns and the
box's four edges: each step measures the frustum at its parameters and at each one moved by
``step`` (the numeric Jacobian) and solves the 4x4 system by Gaussian elimination with partial
pivoting (LAPACK's LU, in a loop); a system without a pivot, or with more measurements than
unknowns, takes the least-squares step of :func:`least_squares` (numpy's ``lstsq``, in loops). In
Python a step was some 30 numpy calls (about 60 µs); here the whole fit is one call. Nothing here
calls numpy's linear algebra, which numba builds on scipy's LAPACK and BLAS: the onboard install,
without scipy, compiles these fits too.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.features.images_kernels import outline_images
from percept.perception.features.least_squares_kernels import least_squares
from percept.perception.features.solids_kernels import balls, frusta

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
            return least_squares(a, b, _EPS * n)  # numpy's default rcond
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


BOX = 0
"""Measuring a frustum of a given top-to-bottom ratio by its box's four edges."""
BALL = 1
"""Measuring a ball on the ground by its box's four edges and its outline's area, each over its
noise ``sigma``."""
FRUSTUM = 2
"""Measuring a frustum and its top-to-bottom ratio (the fifth unknown, kept in [0, 1]) by its
box's four edges and its outline's area."""


@jit
def _measure(
    kind: int,
    params: np.ndarray,
    k: float,
    sigma: np.ndarray,
    rim: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    K: np.ndarray,
) -> np.ndarray:
    """The measurements (n, 4 or 5) of the solids ``params`` (n, 4, 3 or 5) of ``kind``."""
    if kind == BOX:
        rows = np.empty((params.shape[0], 5))
        rows[:, :4] = params
        rows[:, 4] = k
        return outline_images(frusta(rows, rim), R, t, K, False)[:, :4].copy()
    if kind == FRUSTUM:
        return outline_images(frusta(params, rim), R, t, K, True)
    return outline_images(balls(params, t[0], t[1], t[2], rim), R, t, K, True) / sigma


@jit
def solid_newton(
    kind: int,
    target: np.ndarray,
    start: np.ndarray,
    k: float,
    sigma: np.ndarray,
    weights: np.ndarray,
    rim: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    K: np.ndarray,
    iterations: int,
    step: float,
    tolerance: float,
    settled: float,
    moved: float,
) -> tuple[bool, np.ndarray]:
    """The parameters near ``start`` whose measurements (:data:`BOX`: x, y, bottom diameter and
    height of the frustum of ratio ``k``; :data:`BALL`: x, y and diameter of the ball, over
    ``sigma``; :data:`FRUSTUM`: those of the box and the ratio) are ``target``, the least-squares
    ones when there are more measurements than unknowns; the solids' rims drawn with the points
    of ``rim``, seen by the camera ``R``, ``t``, ``K`` (as :func:`outline_images`). Settled when
    every measurement is within ``tolerance`` of its target, a step moves no parameter by
    ``settled`` or (``moved`` > 0) no measurement by ``moved``, each measurement times its
    ``weights`` (pixels); a frustum's ratio stepping out of [0, 1] is clipped to it, and that is
    the answer. False when a step leaves the solids of positive size in front of the camera or
    ``iterations`` steps do not settle."""
    n = start.shape[0]
    p = start.copy()
    rows = np.empty((n + 1, n))
    for _ in range(iterations):
        for row in range(n + 1):
            rows[row] = p
            if row > 0:
                rows[row, row - 1] = p[row - 1] + step
        measured = _measure(kind, rows, k, sigma, rim, R, t, K)
        if not np.isfinite(measured).all():
            return False, p
        residual = measured[0] - target
        if np.abs(residual * weights).max() < tolerance:
            return True, p
        jacobian = np.ascontiguousarray((measured[1:] - measured[0]).T / step)
        if jacobian.shape[0] == n:
            delta = solve4(jacobian, residual)
        else:
            delta = least_squares(jacobian, residual, _EPS * jacobian.shape[0])
        p -= delta
        if p[2] <= 0 or (n > 3 and p[3] <= 0):
            return False, p
        if kind == FRUSTUM and not 0.0 <= p[4] <= 1.0:
            p[4] = min(max(p[4], 0.0), 1.0)
            return True, p
        if np.abs(delta).max() < settled:
            return True, p
        if moved > 0 and _largest_change(jacobian, delta, weights) < moved:
            return True, p
    return False, p


@jit
def _largest_change(jacobian: np.ndarray, delta: np.ndarray, weights: np.ndarray) -> float:
    """``np.abs((jacobian @ delta) * weights).max()``: the most a step ``delta`` moves a
    measurement, each times its weight (a loop: ``@`` would call BLAS)."""
    largest = 0.0
    for row in range(jacobian.shape[0]):
        moved = 0.0
        for col in range(jacobian.shape[1]):
            moved += jacobian[row, col] * delta[col]
        largest = max(largest, abs(moved * weights[row]))
    return largest
