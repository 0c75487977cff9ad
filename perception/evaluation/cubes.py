"""Frames of upright boxes on a uniform floor rendered from a known camera and pose, for tests
and benchmarks of anchors while the head moves
(:mod:`percept.perception.tracking.permanence.memory`).

The floor has one colour, so a background model calibrated at one head pose holds at every pose,
and the anchors can be tested apart from a background that follows the camera. Each box's image
is the convex hull of its projected corners in one flat colour, nearer boxes drawn over farther
ones, with Gaussian camera noise; each box's true image box comes with the frame."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, rpy_matrix
from percept.perception.evaluation.tracking import iou
from percept.perception.tracking.anchors import Anchor

FLOOR = (120, 120, 120)
RED, GREEN, YELLOW = (40, 40, 220), (40, 190, 40), (30, 210, 230)


def head_pose(pan: float, tilt: float = 0.6, height: float = 0.4) -> CameraPose:
    """A camera ``height`` metres above the robot's origin, turned ``pan`` left and ``tilt``
    down (radians) about its own centre."""
    return CameraPose(R=rpy_matrix((0.0, tilt, pan)), t=np.array([0.0, 0.0, height]))


@dataclass(frozen=True)
class Cube:
    """An upright box of ``side`` x ``side`` x ``height`` metres (a cube by default) on the
    floor, at (x, y) from frame ``start`` to ``stop``; after frame ``moved_at`` at (x, y) +
    ``moved``."""

    colour: tuple[int, int, int]
    x: float
    y: float
    side: float = 0.1
    height: float | None = None
    start: int = 0
    stop: int = 10**6
    moved_at: int = 10**6
    moved: tuple[float, float] = (0.0, 0.0)

    def corners(self, frame: int) -> np.ndarray:
        dx, dy = self.moved if frame >= self.moved_at else (0.0, 0.0)
        h = self.side / 2
        return np.array(
            [
                (self.x + dx + sx * h, self.y + dy + sy * h, z)
                for sx in (-1, 1)
                for sy in (-1, 1)
                for z in (0.0, self.side if self.height is None else self.height)
            ]
        )


def render(
    cubes: list[Cube],
    frame: int,
    camera: CameraModel,
    at: CameraPose,
    rng: np.random.Generator,
) -> tuple[np.ndarray, list[tuple[float, float, float, float] | None]]:
    """The BGR image of ``cubes`` at ``frame`` seen with ``camera`` from ``at``, and each
    cube's box (None when it is not in the scene or not wholly in the image)."""
    W, H = camera.width, camera.height
    image = np.empty((H, W, 3), np.float64)
    image[:] = FLOOR
    boxes: list[tuple[float, float, float, float] | None] = [None] * len(cubes)
    present = [(i, c) for i, c in enumerate(cubes) if c.start <= frame < c.stop]
    far_first = sorted(present, key=lambda ic: -np.linalg.norm(ic[1].corners(frame) - at.t))
    for i, cube in far_first:
        uv = camera.project((cube.corners(frame) - at.t) @ at.R)
        hull = cv2.convexHull(np.round(uv).astype(np.int32))
        cv2.fillConvexPoly(image, hull, cube.colour)
        left, top = uv.min(axis=0)
        right, bottom = uv.max(axis=0)
        if left >= 0 and top >= 0 and right < W and bottom < H:
            boxes[i] = (left, top, right - left, bottom - top)
    image += rng.normal(0.0, 2.0, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8), boxes


def matched_id(
    anchors: Sequence[Anchor], box: tuple[float, float, float, float] | None
) -> str | None:
    """The id of the visible anchor that overlaps the true ``box`` best, when by IoU >= 0.5."""
    visible = [a for a in anchors if a.visible]
    if box is None or not visible:
        return None
    overlaps = iou(np.array([box], float), np.array([a.bbox for a in visible]))[0]
    i = int(np.argmax(overlaps))
    return visible[i].id if overlaps[i] >= 0.5 else None
