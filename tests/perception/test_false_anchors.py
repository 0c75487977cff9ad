"""False anchors: unpaired anchors counted per frame, persistent ones over a time limit."""

from __future__ import annotations

import numpy as np

from percept.perception.evaluation.false_anchors import false_seconds, persistent


def rows(*boxes: tuple[int, int, float, float, float, float]) -> np.ndarray:
    return np.array([[f, i, x, y, w, h, 1, -1, -1, -1] for f, i, x, y, w, h in boxes], float)


def test_an_anchor_off_its_object_is_false_and_one_on_it_is_not() -> None:
    truth = [(f, 1, 10, 10, 20, 20) for f in range(1, 31)]
    gt = rows(*truth)
    on = [(f, 7, 11, 10, 20, 20) for f in range(1, 31)]  # IoU 0.9: the object's anchor
    off = [(f, 8, 60, 60, 20, 20) for f in range(1, 21)]  # nothing there: false for 20 frames
    half = [(f, 9, 20, 10, 20, 20) for f in range(21, 31)]  # IoU 1/3 with the object
    seconds = false_seconds(gt, rows(*on, *off, *half), fps=10.0)
    assert seconds == {8: 2.0, 9: 1.0}
    assert persistent(seconds, 1.5) == 1
    assert persistent(seconds, 2.0) == 0


def test_two_anchors_on_one_object_leave_one_false() -> None:
    gt = rows((1, 1, 10, 10, 20, 20))
    hyp = rows((1, 5, 10, 10, 20, 20), (1, 6, 11, 11, 20, 20))
    assert false_seconds(gt, hyp, fps=1.0) == {6: 1.0}


def test_no_truth_in_a_frame_makes_every_anchor_false() -> None:
    gt = rows((1, 1, 10, 10, 20, 20))
    assert false_seconds(gt, rows((2, 3, 10, 10, 20, 20)), fps=2.0) == {3: 0.5}
