"""The moving-head measures (:mod:`percept.perception.evaluation.moving_head`) on hand-made
track tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from percept.perception.evaluation.moving_head import (
    anchors_per_object,
    frame_matches,
    reidentification,
    relative_ground_errors,
)


def track(obj: int, frames: range, left: float = 10.0) -> list[list[float]]:
    """MOT rows of ``obj`` in ``frames``: a 20x20 box at (left, 50)."""
    return [[f, obj, left, 50.0, 20.0, 20.0, 1, -1, -1, -1] for f in frames]


def table(*tracks: list[list[float]]) -> np.ndarray:
    return np.array([row for t in tracks for row in t], float)


def test_anchors_per_object_counts_the_objects_of_the_ground_truth():
    gt = table(track(1, range(1, 5)), track(2, range(1, 5), 100), track(3, range(3, 9), 200))
    assert anchors_per_object(4, gt) == pytest.approx(4 / 3)
    assert math.isnan(anchors_per_object(2, np.zeros((0, 10))))


def test_frame_matches_pair_boxes_that_overlap():
    gt = table(track(1, range(1, 3)), track(2, range(1, 3), 100))
    hyp = table(track(7, range(1, 3), 12), track(8, range(2, 3), 160))  # 8 overlaps nothing
    assert frame_matches(gt, hyp) == {1: {1: 7}, 2: {1: 7}}


def test_reidentification_counts_returns_after_a_long_enough_absence():
    gt = table(
        # object 1 leaves for 20 frames and comes back to the anchor it had (7)
        track(1, range(1, 11)),
        track(1, range(31, 41)),
        # object 2 leaves for 20 frames and comes back to a new anchor (9 instead of 8)
        track(2, range(1, 11), 100),
        track(2, range(31, 41), 100),
        # object 3 flickers at the border: 3 frames missing are no return
        track(3, range(1, 11), 200),
        track(3, range(14, 41), 200),
        # object 4 never had an anchor before it left: nothing to re-identify
        track(4, range(1, 11), 300),
        track(4, range(31, 41), 300),
    )
    hyp = table(
        track(7, range(1, 11)),
        track(7, range(33, 41)),  # found again 2 frames after its return
        track(8, range(1, 11), 100),
        track(9, range(31, 41), 100),
        track(5, range(1, 41), 200),
        track(6, range(31, 41), 300),
    )
    got = reidentification(gt, hyp, min_gap=15, grace=30)
    assert (got.returns, got.same) == (2, 1)
    assert got.fraction == 0.5
    # a return found only after the grace period is not re-identified
    late = reidentification(gt, hyp, min_gap=15, grace=1)
    assert (late.returns, late.same) == (2, 0)
    assert math.isnan(reidentification(gt[:0], hyp).fraction)


def test_relative_ground_errors_are_fractions_of_the_distance():
    truth = np.array([[1.0, 0.0], [0.0, 2.0]])
    estimated = np.array([[1.02, 0.0], [0.0, 1.9]])
    viewpoint = np.zeros((2, 2))
    np.testing.assert_allclose(relative_ground_errors(estimated, truth, viewpoint), [0.02, 0.05])
