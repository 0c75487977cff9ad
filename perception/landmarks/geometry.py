"""Pure geometry of markers on boxes and of angles on the ground plane."""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from percept.kinematics.pose import marker_on_box
from percept.perception.landmarks.settings import BoxSettings, MarkerSettings


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
    """The 4x4 transform box <- marker: where ``marker`` sits on ``box``
    (:func:`percept.kinematics.pose.marker_on_box`)."""
    return marker_on_box(box.size, marker.face, marker.offset, marker.roll)
