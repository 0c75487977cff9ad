"""Constant-velocity Kalman filters of boxes (§4.4), all anchors stepped together.

State ``s = (x, y, w, h, dx, dy, dw, dh)`` per box, covariance 8x8, transition ``A`` adding each
rate to its value once per frame, ``Q = q I_8``, measurement ``z = (x, y, w, h)`` through
``H = [I_4 0]``, ``R = r I_4``. The update is the textbook one that SPEC §4.4 restores::

    K = P H^T (H P H^T + R)^-1,   s = s + K (z - H s),   P = (I - K H) P

These are the equations of filterpy's ``KalmanFilter`` (the tests check the two agree to
1e-9), but applied to all boxes with one batched numpy call per step: a filterpy predict and
update cost about 20 us per object in Python, half the frame budget at 176x144 with 8 objects.
With ``H = [I 0]``, ``H P H^T`` and ``P H^T`` are slices of ``P``.
"""

from __future__ import annotations

import numpy as np


class BoxFilters:
    """Kalman filters of ``len(self)`` boxes; row ``i`` of ``x`` and ``P`` is box ``i``."""

    def __init__(self, q: float, r: float, p0_position: float, p0_velocity: float) -> None:
        self.A = np.eye(8)
        self.A[:4, 4:] = np.eye(4)
        self.Q = q * np.eye(8)
        self.R = r * np.eye(4)
        self.P0 = np.diag([p0_position] * 4 + [p0_velocity] * 4)
        self.x = np.zeros((0, 8))
        self.P = np.zeros((0, 8, 8))

    def __len__(self) -> int:
        return len(self.x)

    def add(self, z: np.ndarray) -> None:
        """Start filters at measurements ``z`` (k, 4), at rest, with covariance ``P0``."""
        x = np.zeros((len(z), 8))
        x[:, :4] = z
        self.x = np.concatenate([self.x, x])
        self.P = np.concatenate([self.P, np.broadcast_to(self.P0, (len(z), 8, 8))])

    def keep(self, rows: np.ndarray) -> None:
        """Drop every filter not selected by ``rows`` (bool mask or indices)."""
        self.x, self.P = self.x[rows], self.P[rows]

    def predict(self) -> None:
        """``s = A s``, ``P = A P A^T + Q`` for every box."""
        self.x = self.x @ self.A.T
        self.P = self.A @ self.P @ self.A.T + self.Q

    def update(self, rows: np.ndarray, z: np.ndarray) -> None:
        """Correct the filters ``rows`` with measurements ``z`` (len(rows), 4)."""
        P = self.P[rows]
        gain = P[:, :, :4] @ np.linalg.inv(P[:, :4, :4] + self.R)
        innovation = z - self.x[rows, :4]
        self.x[rows] += (gain @ innovation[:, :, None])[:, :, 0]
        P = P - gain @ P[:, :4, :]
        self.P[rows] = (P + P.transpose(0, 2, 1)) / 2  # (I - KH)P is symmetric; keep it so
