"""Doubles: two models on one object (a face in another shade inside the object's box) become
one; two objects in other hues, one before the other, keep their models."""

from __future__ import annotations

import numpy as np

from percept.perception.params import PerceptionParams
from percept.perception.segmentation.percepts import PerceptSet
from percept.perception.tracking.anchors import AnchorTracker
from percept.perception.tracking.motion import Motion

BINS = PerceptionParams().regions.bins
BODY = (100.0, 80.0, 60.0, 60.0)
"""An object's box; the face below lies inside it."""
FACE = (104.0, 82.0, 50.0, 18.0)


def histograms(y: int, cr: int, cb: int) -> np.ndarray:
    """(3, BINS): all of each channel in the bin of its value."""
    out = np.zeros((3, BINS))
    for channel, value in enumerate((y, cr, cb)):
        out[channel, value * BINS // 256] = 1.0
    return out


RED = histograms(80, 170, 110)
LIT_RED = histograms(170, 200, 95)
"""The same hue lit more: Cr - 128 and Cb - 128 scaled together, Y much higher."""
BLUE = histograms(170, 110, 200)


def frame(face: np.ndarray) -> PerceptSet:
    """The object's body and a face of colour ``face``, in regions of their own (the colour
    split cut them apart)."""
    return PerceptSet(
        boxes=np.array([BODY, FACE]),
        histograms=np.array([RED, face]),
        counts=np.array([3000, 800]),
        regions=np.array([0, 1]),
    )


def still() -> Motion:
    """No motion anywhere (no previous frame)."""
    grid = np.zeros((200, 320, 3), np.uint8)
    return Motion(grid, None, (grid, grid), None)


def track(face: np.ndarray, frames: int = 10) -> AnchorTracker:
    tracker = AnchorTracker(PerceptionParams().anchors, 320, 200, BINS)
    for k in range(frames):
        tracker.predict()
        tracker.update(frame(face), still(), k / 15)
    return tracker


def test_a_face_in_another_shade_of_the_objects_hue_is_merged_and_not_made_again() -> None:
    tracker = track(LIT_RED)
    # Both made in the first frame; the younger is the double of the older from the second on,
    # and the face, unassociated in every frame after, gives no model again.
    assert tracker.ids == ["o1"]
    assert tracker.created_count == 2
    assert np.allclose(tracker.boxes[0], BODY, atol=1.0)


def test_an_object_in_another_hue_before_a_larger_one_keeps_its_anchor() -> None:
    tracker = track(BLUE)
    assert tracker.ids == ["o1", "o2"]
    assert tracker.created_count == 2


def test_a_double_of_a_model_missed_in_its_frame_is_taken_by_that_model() -> None:
    """The object's body seen, then in one frame only its lit face (the body's percept missed):
    the face is no new model (it would be deleted as a double the next frame the body is seen,
    and made again whenever the body is missed) but the body's model takes it."""
    tracker = AnchorTracker(PerceptionParams().anchors, 320, 200, BINS)
    body = PerceptSet(np.array([BODY]), np.array([RED]), np.array([3000]), np.array([0]))
    face = PerceptSet(np.array([FACE]), np.array([LIT_RED]), np.array([800]), np.array([0]))
    for k, percepts in enumerate([body, body, face, body, face, body]):
        tracker.predict()
        anchors = tracker.update(percepts, still(), k / 15)
    assert [a.id for a in anchors] == ["o1"]
    assert tracker.created_count == 1
