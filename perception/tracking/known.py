"""Known objects: things whose place and size are known without the foreground, as the marker
boxes are (their pose from the markers, their size from the experiment). What the foreground
shows of them is no new object: a turning head sees their faces and edges against a background
learned from elsewhere. Their volume, projected into the image through the camera pose, is where
no percept feeds the anchors.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import TYPE_CHECKING

import cv2
import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, ground_transform, same_pose

if TYPE_CHECKING:
    from percept.perception.landmarks.boxes import BoxEstimator

KNOWN_COVER = 0.5
"""A percept whose box lies this much or more inside a known object's image is of that object."""
MARGIN = 3.0
"""Pixels the known objects' images are widened by: the box poses are off by a few millimetres
and a degree, the camera pose by the joints' resolution."""


@functools.lru_cache(maxsize=64)
def box_corners(x: float, y: float, theta: float, size: tuple[float, float, float]) -> np.ndarray:
    """The 8 corners (8, 3) in the ground frame of a box standing on the ground with its
    footprint's centre at ``(x, y)``, its front heading ``theta`` and ``size`` (length along
    the front's heading, width, height; metres). Kept for the next call (read only): a box
    stays where its markers put it for many frames."""
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
    corners = np.asarray(local @ T[:3, :3].T + T[:3, 3])
    corners.flags.writeable = False
    return corners


def marker_boxes(estimator: BoxEstimator, t: float) -> list[np.ndarray]:
    """The corners of the marker boxes where ``estimator``'s markers have placed them by time
    ``t``, each box its experiment's size: the known objects of a frame at ``t`` (the daemon's
    and ``percept track``'s alike)."""
    sizes = {b.id: b.size for b in estimator.settings.boxes}
    return [
        box_corners(b.x, b.y, b.theta, sizes[b.id]) for b in estimator.boxes(t) if b.id in sizes
    ]


def known_outlines(
    solids: Sequence[np.ndarray], camera: CameraModel, pose: CameraPose
) -> list[np.ndarray]:
    """The image outline (k, 2) (pixels, float32, convex) of each of ``solids`` (its corners in
    the ground frame) seen from ``pose``: the convex hull of its corners' images, which is the
    image of a convex solid, widened by :data:`MARGIN` on every side. A solid partly behind the
    camera has none. (The box around the corners' images is larger by the triangles at its
    corners, where an object standing beside the solid is seen.)"""
    outlines = []
    square = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float) * MARGIN
    for corners in solids:
        uv = camera.project((corners - pose.t) @ pose.R)
        if not np.isfinite(uv).all():
            continue
        widened = (uv[:, None, :] + square[None, :, :]).reshape(-1, 2).astype(np.float32)
        outlines.append(cv2.convexHull(widened).reshape(-1, 2))
    return outlines


class KnownOutlines:
    """:func:`known_outlines` seen from one camera, the last answer kept while its solids and
    the pose stay the same to the bit: with the head and the boxes still, every frame's."""

    def __init__(self, camera: CameraModel) -> None:
        self.camera = camera
        self._last: tuple[CameraPose, list[np.ndarray], list[np.ndarray]] | None = None

    def __call__(self, solids: Sequence[np.ndarray], pose: CameraPose) -> list[np.ndarray]:
        last = self._last
        if (
            last is not None
            and same_pose(last[0], pose)
            and len(last[1]) == len(solids)
            and all(map(np.array_equal, last[1], solids))
        ):
            return last[2]
        outlines = known_outlines(solids, self.camera, pose)
        self._last = (pose, list(solids), outlines)
        return outlines


def known_cover(boxes: np.ndarray, outlines: Sequence[np.ndarray]) -> np.ndarray:
    """(n,): the largest share of each image box of ``boxes`` (n, 4) (left, top, width,
    height) that lies inside one of ``outlines`` (:func:`known_outlines`); 0 with none."""
    out = np.zeros(len(boxes))
    for i, (left, top, width, height) in enumerate(np.asarray(boxes, dtype=float)):
        area = width * height
        if area <= 0:
            continue
        right, bottom = left + width, top + height
        rect = np.array(
            [[left, top], [right, top], [right, bottom], [left, bottom]], dtype=np.float32
        )
        for outline in outlines:
            inside, _ = cv2.intersectConvexConvex(rect, outline)
            out[i] = max(out[i], inside / area)
    return out
