"""The demo's precision against the simulated truth (:class:`~percept.runtime.record.scorecard.
Precision`): MOTA, IDF1 and the false anchors, counted over world models as the demo's summary
reads them from a recording."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from percept.runtime.net.messages import World, WorldObject
from percept.runtime.record.drawing import FALSE_COLOUR, draw_anchors, draw_map
from percept.runtime.record.scorecard import Precision, TruthObject

CAMERA = {"R": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "t": [0.0, 0.0, 0.45]}
POSE = (-0.5, 0.0, 0.0)  # the robot 0.5 m behind the world's origin, facing +x
TRUTH = [
    TruthObject(1, "red-block", 0.0, 0.0, (0.04, 0.04, 0.1), (200, 30, 35)),
    TruthObject(2, "blue-cylinder", 0.1, 0.2, (0.05, 0.05, 0.07), (30, 70, 200)),
]


def _anchor(number: int, x: float, y: float) -> WorldObject:
    """Anchor ``o<number>`` (as the daemon names them) at (x, y) on the ground."""
    return WorldObject(f"o{number}", (10.0 * number, 20.0, 12.0, 14.0), {"x": x, "y": y})


def _world(stamp: float, *objects: WorldObject) -> World:
    return World("a", 1.8e9 + stamp, round(stamp * 10), CAMERA, objects)


def test_true_anchors_score_one_and_a_lasting_false_one_is_counted() -> None:
    """Two objects tracked for 20 s (in the robot's frame 0.5 m ahead, and 0.6 m ahead 0.2 m
    to the left); a third anchor on nothing appears at 5 s (false for 15 s), a fourth for 4 s."""
    precision = Precision(POSE)
    false_seen = []
    for k in range(21):
        objects = [_anchor(7, 0.51, 0.01), _anchor(8, 0.6, 0.19)]
        if k >= 5:
            objects.append(_anchor(9, 1.4, -0.6))
        if 10 <= k < 14:
            objects.append(_anchor(10, 0.5, -0.5))
        false_seen.append(precision.add(_world(float(k), *objects), TRUTH))
    assert false_seen[0] == set() and false_seen[11] == {"o9", "o10"}
    mota, idf1 = precision.scores()
    # 42 true boxes, 16 + 4 false ones, no miss, no switch.
    assert mota == pytest.approx(1 - 20 / 42, abs=1e-4)
    assert idf1 == pytest.approx(2 * 42 / (42 + 62), abs=1e-4)
    assert precision.long_false() == 1  # 9 for 15 s; 10 only for 3 s
    assert sum(precision.false_counts) / len(precision.false_counts) == pytest.approx(20 / 21)


def test_a_switch_and_a_miss_lower_mota() -> None:
    """The red block's anchor is replaced by another (an identity switch); the cylinder is
    missed in one world model."""
    precision = Precision(POSE)
    precision.add(_world(0.0, _anchor(7, 0.5, 0.0), _anchor(8, 0.6, 0.2)), TRUTH)
    precision.add(_world(1.0, _anchor(11, 0.5, 0.0)), TRUTH)
    mota, _ = precision.scores()
    assert mota == pytest.approx(1 - 2 / 4)
    assert precision.long_false() == 0


def test_false_anchors_are_crossed_out_in_the_pictures() -> None:
    world = _world(0.0, _anchor(7, 0.5, 0.0), _anchor(9, 1.4, -0.6))
    image = np.full((80, 160, 3), 128, np.uint8)
    marked = draw_anchors(image, world, false={"o9"})
    plain = draw_anchors(image, world)
    red = np.all(marked == FALSE_COLOUR, axis=2)
    assert red[20:34, 90:102].any() and not red[20:34, 70:82].any()
    assert not np.all(plain == FALSE_COLOUR, axis=2).any()
    reds = cv2.inRange(draw_map(world, 300, false={"o9"}), FALSE_COLOUR, FALSE_COLOUR)
    assert reds.any() and not cv2.inRange(draw_map(world, 300), FALSE_COLOUR, FALSE_COLOUR).any()
