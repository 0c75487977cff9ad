"""Constant-velocity Kalman filters of boxes (§4.4), all anchors stepped together.

State ``s = (x, y, w, h, dx, dy, dw, dh)`` per box, transition ``A`` adding each rate to its
value once per frame, process noise ``Q = q I_8``, measurement ``z = (x, y, w, h)`` through
``H = [I_4 0]`` with noise ``R = r I_4``, and the textbook update that SPEC §4.4 restores::

    K = P H^T (H P H^T + R)^-1,   s = s + K (z - H s),   P = (I - K H) P

With these ``Q``, ``R`` and an initial ``P = diag(p_pos I_4, p_vel I_4)``, the four coordinates
are independent copies of one (value, rate) filter with the same covariance, so the 8x8
covariance is always ``[[a I, b I], [b I, c I]]`` and three numbers per box carry it exactly
(:attr:`BoxFilters.P` rebuilds the matrices). The equations above then reduce to a handful of
operations per box, with ``H P H^T + R = (a + r) I``, which one compiled loop over all boxes
makes in place (:mod:`percept.perception.tracking.kalman_kernels`; numpy's array expressions
over a few boxes cost more in calls than in arithmetic). The tests check every
state and covariance against filterpy's ``KalmanFilter`` to 1e-9; stepping filterpy objects one by
one costs about 20 us per object, half the frame budget at 176x144 with 8 objects.

When the camera turns between two frames, :meth:`BoxFilters.warp` re-expresses every state in the
new view before the prediction, so that a box's rate is the object's own motion in the image and
not the head's (the covariances are kept: the view's change is known, not noise).
"""

from __future__ import annotations

import math

import numpy as np

from percept.perception.tracking import kalman_kernels as kalman


class BoxFilters:
    """Kalman filters of ``len(self)`` boxes; row ``i`` of ``x`` and ``cov`` is box ``i``."""

    def __init__(self, q: float, r: float, p0_position: float, p0_velocity: float) -> None:
        self.q, self.r = float(q), float(r)
        self.cov0 = np.array([p0_position, 0.0, p0_velocity])
        self.x = np.zeros((0, 8))
        self.cov = np.zeros((0, 3))
        """(n, 3): a, b, c of each box's covariance [[a I, b I], [b I, c I]]."""

    def __len__(self) -> int:
        return len(self.x)

    @property
    def A(self) -> np.ndarray:
        """The 8x8 transition matrix."""
        return np.block([[np.eye(4), np.eye(4)], [np.zeros((4, 4)), np.eye(4)]])

    @property
    def P(self) -> np.ndarray:
        """(n, 8, 8) covariance matrices."""
        a, b, c = self.cov.T
        blocks = np.stack([np.stack([a, b], 1), np.stack([b, c], 1)], 1)  # (n, 2, 2)
        return np.einsum("nij,kl->nikjl", blocks, np.eye(4)).reshape(-1, 8, 8)

    def add(self, z: np.ndarray) -> None:
        """Start filters at measurements ``z`` (k, 4), at rest, with the initial covariance."""
        self.x = np.concatenate([self.x, np.zeros((len(z), 8))])
        self.cov = np.concatenate([self.cov, np.zeros((len(z), 3))])
        self.restart(np.arange(len(self) - len(z), len(self)), z)

    def restart(self, rows: np.ndarray, z: np.ndarray) -> None:
        """Start the filters ``rows`` again at measurements ``z`` (len(rows), 4), at rest, with
        the initial covariance."""
        self.x[rows] = 0.0
        self.x[rows, :4] = z
        self.cov[rows] = self.cov0

    def keep(self, rows: np.ndarray) -> None:
        """Drop every filter not selected by ``rows`` (bool mask or indices)."""
        self.x, self.cov = self.x[rows], self.cov[rows]

    def warp(self, H: np.ndarray) -> None:
        """Move every box into the view that the homography ``H`` (3x3, old pixels to new)
        maps to: the middle of its lower edge (an object's foot, on the ground, where ``H`` is
        exact) goes where ``H`` takes it, width and height scale with the lengths that ``H``'s
        Jacobian there gives the image's axes, and the rates turn with that Jacobian. A box
        whose foot ``H`` sends behind the camera is left as it is."""
        x = self.x
        foot = np.stack([x[:, 0], x[:, 1] + x[:, 3] / 2, np.ones(len(x))], axis=1)
        kalman.warp(x, np.ascontiguousarray(H, dtype=float), foot @ H.T)

    @property
    def boxes(self) -> np.ndarray:
        """(n, 4) boxes (left, top, width, height) of the states."""
        return kalman.boxes(self.x)

    def predict(self, min_size: float = -math.inf) -> None:
        """``s = A s``, ``P = A P A^T + Q`` for every box; then a width or height below
        ``min_size`` becomes ``min_size``."""
        kalman.predict(self.x, self.cov, self.q, float(min_size))

    def update(self, rows: np.ndarray, z: np.ndarray) -> None:
        """Correct the filters ``rows`` (indices) with measurements ``z`` (len(rows), 4)."""
        kalman.update(self.x, self.cov, rows, z, self.r)
