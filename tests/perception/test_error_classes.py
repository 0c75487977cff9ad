"""Error classes: each unpaired box named by what is near it (nothing, a bigger or a smaller
partner), counted over frames and summed over sequences."""

from __future__ import annotations

import numpy as np

from percept.perception.evaluation.error_classes import NONE, ErrorClasses, error_classes


def rows(*boxes: tuple[int, int, float, float, float, float]) -> np.ndarray:
    return np.array([[f, i, x, y, w, h, 1, -1, -1, -1] for f, i, x, y, w, h in boxes], float)


def test_each_unpaired_box_is_named_by_its_nearest_partner() -> None:
    gt = rows(
        (1, 1, 10, 10, 20, 20),  # paired with anchor 11
        (1, 2, 100, 10, 20, 20),  # nothing near: a miss
        (1, 3, 200, 10, 20, 20),  # inside anchor 13, which also covers a neighbour: merged
        (1, 4, 225, 10, 20, 20),  # its neighbour (IoU with 13 below 0.5 too): merged
        (1, 5, 10, 100, 40, 40),  # anchor 15 covers its top quarter: cut
    )
    hyp = rows(
        (1, 11, 11, 10, 20, 20),
        (1, 12, 150, 150, 10, 10),  # nothing near: a false box
        (1, 13, 198, 8, 50, 24),  # bigger than objects 3 and 4
        (1, 15, 10, 100, 20, 20),  # a quarter of object 5: on a part
    )
    found = error_classes(gt, hyp)
    assert found == ErrorClasses(
        boxes=5, matched=1, misses=1, false_boxes=1, merged=2, too_big=1, on_a_part=1, cut=1
    )
    assert found.shares()["merged"] == 0.4


def test_frames_without_truth_or_anchors_count_every_box_alone() -> None:
    gt = rows((1, 1, 10, 10, 20, 20))
    hyp = rows((2, 7, 10, 10, 20, 20))
    assert error_classes(gt, hyp) == ErrorClasses(1, 0, 1, 1, 0, 0, 0, 0)


def test_objects_are_clipped_to_the_image_before_pairing() -> None:
    gt = rows((1, 1, -30, 10, 50, 20))  # three fifths outside the image
    hyp = rows((1, 7, 0, 10, 20, 20))  # the half in view
    assert error_classes(gt, hyp).matched == 0
    assert error_classes(gt, hyp, image_size=(320, 200)).matched == 1


def test_counts_add_over_sequences_and_shares_are_of_the_true_boxes() -> None:
    a = ErrorClasses(10, 8, 1, 2, 1, 0, 0, 0)
    b = ErrorClasses(30, 30, 0, 2, 0, 0, 0, 0)
    total = NONE + a + b
    assert total == ErrorClasses(40, 38, 1, 4, 1, 0, 0, 0)
    assert total.shares()["false_boxes"] == 0.1
    assert ErrorClasses.from_counts(vars(total)) == total
    assert NONE.shares()["misses"] == 0.0
