"""The minimum-norm least-squares solution of a small linear system, as numpy's ``lstsq`` gives
it, in loops: the steps of the footprint fit's Newton method
(:mod:`percept.perception.features.newton_kernels`) with more measurements than unknowns, or
without a pivot.

numba compiles ``np.linalg.lstsq`` (and ``@`` on arrays) by calling LAPACK and BLAS through
scipy's bindings, which the onboard install leaves out; so the kernels solve their systems of at
most a few rows and columns here. The method is the one-sided Jacobi SVD (Hestenes): plane
rotations orthogonalise the columns of ``a``, so ``a v = w`` with ``v`` orthogonal and the columns
of ``w`` the left singular vectors times the singular values. Chosen over a QR decomposition
with column pivoting because it yields the singular values themselves, so the rank is decided by
numpy's rule (those at most ``rcond`` times the largest are dropped), which the diagonal of a
pivoted QR only approximates; because its accuracy does not suffer from columns of different
scales (a Jacobian's columns are metres of position and of size, its rows pixels); and because it
is one short loop with no special case for a rank-deficient system. A 5x3 system takes three or
four sweeps (the last finds nothing left to rotate), a 5x5 one five or six.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit

_EPS = 2.220446049250313e-16  # float64's machine epsilon
_SWEEPS = 40  # a handful suffice (the convergence is quadratic); a bound against a rounding loop


@jit
def least_squares(a: np.ndarray, b: np.ndarray, rcond: float) -> np.ndarray:
    """The x (n,) of least norm among those that minimise ``|a x - b|`` for ``a`` (m, n) and
    ``b`` (m,), singular values of ``a`` at most ``rcond`` times the largest taken as zero:
    ``np.linalg.lstsq(a, b, rcond)[0]``. Zero when ``a`` is."""
    m, n = a.shape
    w = a.copy()
    v = np.eye(n)
    for _ in range(_SWEEPS):
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                alpha, beta, gamma = 0.0, 0.0, 0.0
                for i in range(m):
                    alpha += w[i, p] * w[i, p]
                    beta += w[i, q] * w[i, q]
                    gamma += w[i, p] * w[i, q]
                # Columns orthogonal to working precision (or zero) are left as they are.
                if abs(gamma) <= _EPS * np.sqrt(alpha * beta):
                    continue
                rotated = True
                # The rotation that zeroes the pair's inner product, by its smaller angle.
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0 else -1.0) / (abs(zeta) + np.sqrt(1.0 + zeta * zeta))
                c = 1.0 / np.sqrt(1.0 + t * t)
                s = c * t
                for i in range(m):
                    wp, wq = w[i, p], w[i, q]
                    w[i, p], w[i, q] = c * wp - s * wq, s * wp + c * wq
                for i in range(n):
                    vp, vq = v[i, p], v[i, q]
                    v[i, p], v[i, q] = c * vp - s * vq, s * vp + c * vq
        if not rotated:
            break
    squares = np.zeros(n)  # the singular values squared: the columns' squared norms
    for j in range(n):
        for i in range(m):
            squares[j] += w[i, j] * w[i, j]
    cutoff = rcond * np.sqrt(squares.max())
    x = np.zeros(n)
    for j in range(n):
        if squares[j] == 0.0 or np.sqrt(squares[j]) <= cutoff:
            continue
        along = 0.0  # b along the left singular vector, times the singular value
        for i in range(m):
            along += w[i, j] * b[i]
        along /= squares[j]
        for i in range(n):
            x[i] += v[i, j] * along
    return x
