"""Known objects (:mod:`percept.perception.tracking.known`): a marker box whose pose and size are
known gets no anchor, however it shows in the foreground; an object beside it still does. Cubes
rendered on a floor (:mod:`percept.perception.evaluation.cubes`), seen by a camera whose head pans,
through the whole perception pipeline."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from percept.kinematics.camera import CameraModel
from percept.perception.evaluation.cubes import RED, Cube, matched_id, render
from percept.perception.evaluation.cubes import head_pose as pose
from percept.perception.params import PerceptionParams
from percept.perception.pipeline import Perception
from percept.perception.tracking.known import (
    KNOWN_COVER,
    KnownOutlines,
    box_corners,
    known_cover,
    known_outlines,
)

pytestmark = pytest.mark.timeout(60)

W, H = 176, 144
CAMERA = CameraModel.from_opening_angles(math.radians(60), math.radians(47), W, H)
BROWN = (60, 110, 170)  # BGR, a carton
SIDE = 0.18
BOX = Cube(BROWN, 0.85, 0.25, side=SIDE, start=3)  # put down after the calibration
OBJECT = Cube(RED, 0.75, -0.15, side=0.06, start=3)
PANS = [0.0] * 10 + [0.05 * k for k in range(1, 7)] + [0.3] * 10


def test_the_outline_of_a_known_box_holds_its_picture_and_little_more() -> None:
    corners = box_corners(BOX.x, BOX.y, 0.0, (SIDE, SIDE, SIDE))
    assert corners.shape == (8, 3) and corners[:, 2].max() == pytest.approx(SIDE)
    for pan in (0.0, 0.3):
        image, (drawn,) = render([BOX], 5, CAMERA, pose(pan), np.random.default_rng(0))
        assert drawn is not None
        (outline,) = known_outlines([corners], CAMERA, pose(pan))
        rows, cols = np.nonzero(np.abs(image.astype(int) - BROWN).sum(axis=2) < 30)
        assert len(rows) > 100  # the carton's picture
        pixels = zip(cols.tolist(), rows.tolist(), strict=True)
        assert min(cv2.pointPolygonTest(outline, (x, y), False) for x, y in pixels) >= 0
        _, _, w, h = drawn
        assert cv2.contourArea(outline) < 1.6 * w * h  # about its picture, not much more
        # An object in a corner of the box around the outline is not taken for the box's.
        (x0, y0), (x1, y1) = outline.min(axis=0), outline.max(axis=0)
        corners_of_box = [(x0, y0), (x1 - 6, y0), (x0, y1 - 6), (x1 - 6, y1 - 6)]
        cover = known_cover(np.array([(x, y, 6, 6) for x, y in corners_of_box]), [outline])
        assert cover.min() < KNOWN_COVER
    behind = box_corners(-1.0, 0.0, 0.0, (SIDE, SIDE, SIDE))
    assert known_outlines([behind], CAMERA, pose(0.0)) == []


def test_known_outlines_are_projected_again_only_when_the_pose_or_a_box_changes() -> None:
    outlines = KnownOutlines(CAMERA)
    corners = box_corners(BOX.x, BOX.y, 0.0, (SIDE, SIDE, SIDE))
    first = outlines([corners], pose(0.0))
    # The same pose and box (new objects, equal to the bit): the same answer, not projected.
    assert outlines([corners.copy()], pose(0.0)) is first
    for solids, pan in (([corners], 0.1), ([corners + np.array([0.01, 0, 0])], 0.1), ([], 0.1)):
        again = outlines(solids, pose(pan))
        assert again is not first
        expected = known_outlines(solids, CAMERA, pose(pan))
        assert len(again) == len(expected)
        assert all(np.array_equal(a, b) for a, b in zip(again, expected, strict=True))
        first = again


def _anchored(known: bool) -> tuple[set[str | None], set[str | None], int]:
    """The anchors of the box and of the object over the frames, and the most anchors in one."""
    rng = np.random.default_rng(3)
    perception = Perception(PerceptionParams(), W, H, CAMERA)
    perception.calibrate([render([], 0, CAMERA, pose(0.0), rng)[0] for _ in range(30)])
    solids = [box_corners(BOX.x, BOX.y, 0.0, (SIDE, SIDE, SIDE))] if known else []
    box_ids, object_ids, most = set(), set(), 0
    for f, pan in enumerate(PANS):
        image, (box, obj) = render([BOX, OBJECT], f, CAMERA, pose(pan), rng)
        result = perception.process(image, f / 10.0, pose(pan), known=solids)
        if f >= 6:
            box_ids.add(matched_id(result.anchors, box))
            object_ids.add(matched_id(result.anchors, obj))
        most = max(most, len(result.anchors))
    return box_ids, object_ids, most


def test_a_known_box_gets_no_anchor_and_the_object_beside_it_does() -> None:
    box_ids, object_ids, most = _anchored(known=False)
    assert box_ids != {None}  # unknown, the carton is anchored like any object
    box_ids, object_ids, most = _anchored(known=True)
    assert box_ids == {None}
    assert len(object_ids) == 1 and None not in object_ids  # one anchor, all along
    assert most == 1
