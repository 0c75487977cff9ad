"""Rigid transforms and the camera pose in the robot's ground frame.

Rotations follow URDF: ``rpy = (roll, pitch, yaw)`` about the fixed x, y, z axes, so
``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``. Homogeneous transforms are 4x4 arrays ``T_a_b`` that map
coordinates in frame ``b`` into frame ``a``. Poses on the ground plane are ``(x, y, theta)``; a
marker on a box face is placed by the one convention that the simulated world draws and the
landmark finder inverts (:func:`marker_on_box`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, overload

import numpy as np


@dataclass(frozen=True)
class CameraPose:
    """Where the camera is: ``R`` maps vectors of the chapter's camera frame (x along the optical
    axis, y left, z up) into the ground frame, ``t`` is the camera centre in the ground frame
    (metres). A point ``p_c`` in the camera frame is ``R @ p_c + t`` in the ground frame."""

    R: np.ndarray
    t: np.ndarray

    def as_dict(self) -> dict[str, Any]:
        """``{"R": 3x3 rows, "t": [x, y, z], "frame": "ground"}``, JSON-able."""
        return {
            "R": [[float(v) for v in row] for row in self.R],
            "t": [float(v) for v in self.t],
            "frame": "ground",
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CameraPose:
        """The inverse of :meth:`as_dict`."""
        R = np.asarray(data["R"], dtype=float)
        t = np.asarray(data["t"], dtype=float)
        if R.shape != (3, 3) or t.shape != (3,):
            raise ValueError(f"camera pose needs R 3x3 and t of 3, got {R.shape} and {t.shape}")
        return cls(R=R, t=t)

    @classmethod
    def from_matrix(cls, T: np.ndarray) -> CameraPose:
        """From a 4x4 transform ground <- camera."""
        return cls(R=np.array(T[:3, :3], dtype=float), t=np.array(T[:3, 3], dtype=float))

    def matrix(self) -> np.ndarray:
        """The 4x4 transform ground <- camera."""
        T = np.eye(4)
        T[:3, :3] = self.R
        T[:3, 3] = self.t
        return T


def same_pose(a: CameraPose, b: CameraPose) -> bool:
    """The two poses are equal, to the bit: what was computed from one holds for the other."""
    return a is b or (np.array_equal(a.R, b.R) and np.array_equal(a.t, b.t))


@overload
def wrap(angle: float) -> float: ...
@overload
def wrap(angle: np.ndarray) -> np.ndarray: ...
def wrap(angle: float | np.ndarray) -> float | np.ndarray:
    """``angle`` (radians, a number or an array of them) in [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    """The 3x3 rotation of URDF roll, pitch, yaw: ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
    roll, pitch, yaw = (float(a) for a in rpy)
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of a rotation matrix: the inverse of :func:`rpy_matrix` (pitch in
    [-pi/2, pi/2])."""
    m = np.asarray(R, dtype=float)
    pitch = math.atan2(-m[2, 0], math.hypot(m[0, 0], m[1, 0]))
    return math.atan2(m[2, 1], m[2, 2]), pitch, math.atan2(m[1, 0], m[0, 0])


def transform(xyz: Sequence[float], rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """The 4x4 transform with translation ``xyz`` and URDF rotation ``rpy``."""
    T = np.eye(4)
    T[:3, :3] = rpy_matrix(rpy)
    T[:3, 3] = [float(v) for v in xyz]
    return T


def invert(T: np.ndarray) -> np.ndarray:
    """The inverse of a rigid 4x4 transform."""
    inv = np.eye(4)
    R = T[:3, :3]
    inv[:3, :3] = R.T
    inv[:3, 3] = -R.T @ T[:3, 3]
    return inv


def axis_angle_matrix(axis: Sequence[float] | np.ndarray, angle: float) -> np.ndarray:
    """The 3x3 rotation by ``angle`` about the unit vector ``axis`` (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def ground_transform(x: float, y: float, theta: float) -> np.ndarray:
    """The 4x4 transform ground <- frame of a frame at ``(x, y)`` on the ground, its x axis
    turned by ``theta`` about the vertical; the inverse of :func:`ground_pose`."""
    return transform((x, y, 0.0), (0.0, 0.0, theta))


def ground_pose(T: np.ndarray) -> tuple[float, float, float]:
    """``(x, y, theta)`` on the ground plane of the 4x4 transform ground <- frame: its origin's
    x, y and the heading of its x axis projected onto the ground."""
    return float(T[0, 3]), float(T[1, 3]), math.atan2(float(T[1, 0]), float(T[0, 0]))


FACE_YAW: dict[str, float] = {
    "front": 0.0,
    "left": math.pi / 2,
    "back": math.pi,
    "right": -math.pi / 2,
}
"""Outward normal of each upright face of a box as a yaw angle in the box frame."""


def marker_on_box(
    size: Sequence[float], face: str, offset: Sequence[float], roll: float
) -> np.ndarray:
    """The 4x4 transform box <- marker of a marker on ``face`` of a box of ``size`` (length
    along x, width along y, height; origin at the box's centre), its centre ``offset`` (right,
    up) from the face's centre.

    The marker's z axis is its face's outward normal, its y axis points up (turned by ``roll``
    about the normal), so its x axis points to the right of someone looking at the face.
    """
    length, width, height = size
    yaw = FACE_YAW[face]
    normal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    right = np.cross(up, normal)
    c, s = math.cos(roll), math.sin(roll)
    x_axis = c * right + s * up
    y_axis = -s * right + c * up
    half_depth = length / 2 if face in ("front", "back") else width / 2
    offset_right, offset_up = offset
    centre = normal * half_depth + right * offset_right + up * (height / 2 + offset_up)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x_axis, y_axis, normal, centre
    return T


def quaternion(R: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix, by Shepperd's method: from the largest of the four
    components, so nothing is divided by a small number. (Not scipy's Rotation: importing
    scipy.spatial costs the daemon about 40 MB of memory.)"""
    m = np.asarray(R, dtype=float)
    four = [  # 4 w^2, 4 x^2, 4 y^2, 4 z^2
        1 + m[0, 0] + m[1, 1] + m[2, 2],
        1 + m[0, 0] - m[1, 1] - m[2, 2],
        1 - m[0, 0] + m[1, 1] - m[2, 2],
        1 - m[0, 0] - m[1, 1] + m[2, 2],
    ]
    k = int(np.argmax(four))
    s = 2.0 * float(np.sqrt(four[k]))  # four times that component
    wx, wy, wz = m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]  # 4 wx, 4 wy, 4 wz
    xy, xz, yz = m[0, 1] + m[1, 0], m[0, 2] + m[2, 0], m[1, 2] + m[2, 1]  # 4 xy, 4 xz, 4 yz
    w, x, y, z = (
        (s / 4, wx / s, wy / s, wz / s),
        (wx / s, s / 4, xy / s, xz / s),
        (wy / s, xy / s, s / 4, yz / s),
        (wz / s, xz / s, yz / s, s / 4),
    )[k]
    norm = float(np.sqrt(w * w + x * x + y * y + z * z))
    return x / norm, y / norm, z / norm, w / norm
