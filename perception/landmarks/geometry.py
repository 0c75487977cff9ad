"""Pure geometry of markers on boxes and of poses on the ground plane."""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from perception.landmarks.settings import FACE_YAW, BoxSettings, MarkerSettings


def wrap(angle: float) -> float:
    """``angle`` in [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def circular_mean(angles: Iterable[float], weights: Iterable[float] | None = None) -> float:
    """The mean direction of ``angles`` (radians), optionally weighted; in [-pi, pi]."""
    a = np.asarray(list(angles), dtype=float)
    w = np.ones_like(a) if weights is None else np.asarray(list(weights), dtype=float)
    if a.size == 0:
        raise ValueError("circular mean of no angles")
    return math.atan2(float(np.sum(w * np.sin(a))), float(np.sum(w * np.cos(a))))


def marker_object_points(side: float) -> np.ndarray:
    """The corners (4, 3) of a marker in its own frame, in OpenCV's order (top-left, top-right,
    bottom-right, bottom-left) and as ``cv2.SOLVEPNP_IPPE_SQUARE`` wants them: x right, y up,
    z out of the marker towards the viewer."""
    h = side / 2
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def marker_in_box(box: BoxSettings, marker: MarkerSettings) -> np.ndarray:
    """The 4x4 transform box <- marker: where ``marker`` sits on ``box``.

    The marker's z axis is its face's outward normal, its y axis points up (turned by ``roll``
    about the normal), so its x axis points to the right of someone looking at the face.
    """
    length, width, height = box.size
    yaw = FACE_YAW[marker.face]
    normal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    right = np.cross(up, normal)
    c, s = math.cos(marker.roll), math.sin(marker.roll)
    x_axis = c * right + s * up
    y_axis = -s * right + c * up
    half_depth = length / 2 if marker.face in ("front", "back") else width / 2
    offset_right, offset_up = marker.offset
    centre = normal * half_depth + right * offset_right + up * (height / 2 + offset_up)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x_axis, y_axis, normal, centre
    return T


def ground_pose(T: np.ndarray) -> tuple[float, float, float]:
    """``(x, y, theta)`` on the ground plane of the 4x4 transform ground <- frame: its origin's
    x, y and the heading of its x axis projected onto the ground."""
    return float(T[0, 3]), float(T[1, 3]), math.atan2(float(T[1, 0]), float(T[0, 0]))
