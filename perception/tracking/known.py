"""Known objects: things whose place and size are known without the foreground, as the marker
boxes are (their pose from the markers, their size from the experiment). What the foreground
shows of them is no new object: a turning head sees their faces and edges against a background
learned from elsewhere. Their volume, projected into the image through the camera pose, is where
no percept feeds the anchors.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, ground_transform

if TYPE_CHECKING:
    from percept.perception.landmarks.boxes import BoxEstimator

KNOWN_COVER = 0.5
"""A percept whose box lies this much or more inside a known object's image is of that object."""
MARGIN = 3.0
"""Pixels the known objects' images are widened by: the box poses are off by a few millimetres
and a degree, the camera pose by the joints' resolution."""


def box_corners(x: float, y: float, theta: float, size: tuple[float, float, float]) -> np.ndarray:
    """The 8 corners (8, 3) in the ground frame of a box standing on the ground with its
    footprint's centre at ``(x, y)``, its front heading ``theta`` and ``size`` (length along
    the front's heading, width, height; metres)."""
    length, width, height = size
    local = np.array(
        [
            [sx * length / 2, sy * width / 2, z]
            for sx in (-1, 1)
            for sy in (-1, 1)
            for z in (0.0, height)
        ]
    )
    T = ground_transform(x, y, theta)
    return np.asarray(local @ T[:3, :3].T + T[:3, 3])


def marker_boxes(estimator: BoxEstimator, t: float) -> list[np.ndarray]:
    """The corners of the marker boxes where ``estimator``'s markers have placed them by time
    ``t``, each box its experiment's size: the known objects of a frame at ``t`` (the daemon's
    and ``percept track``'s alike)."""
    sizes = {b.id: b.size for b in estimator.settings.boxes}
    return [
        box_corners(b.x, b.y, b.theta, sizes[b.id]) for b in estimator.boxes(t) if b.id in sizes
    ]


def known_boxes(solids: Sequence[np.ndarray], camera: CameraModel, pose: CameraPose) -> np.ndarray:
    """The image boxes (m, 4) (left, top, width, height; pixels) of ``solids`` (each its
    corners in the ground frame) seen from ``pose``, widened by :data:`MARGIN`; a solid partly
    behind the camera has none. The box of a solid's corners is a little larger than its
    image: what lies in its corners and is mostly there is taken for part of it."""
    if not solids:
        return np.zeros((0, 4))
    corners = np.concatenate(solids)
    uv = camera.project((corners - pose.t) @ pose.R).reshape(len(solids), -1, 2)
    uv = uv[np.isfinite(uv).all(axis=(1, 2))]
    low, high = uv.min(axis=1) - MARGIN, uv.max(axis=1) + MARGIN
    return np.concatenate([low, high - low], axis=1)
