"""Doubles: two models on one object (a face in another shade inside the object's box) become
one; two objects in other hues, one before the other, keep their models."""

from __future__ import annotations

import numpy as np

from percept.perception.colour import Coding
from percept.perception.params import PerceptionParams
from percept.perception.segmentation.percepts import PerceptSet
from percept.perception.tracking.anchors import AnchorTracker, pieces
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
    tracker = AnchorTracker(PerceptionParams().anchors, 320, 200, Coding(BINS, joint=False))
    for k in range(frames):
        tracker.predict()
        tracker.update(frame(face), still(), k / 15)
    return tracker


def test_a_face_in_another_shade_of_the_objects_hue_is_merged_and_not_made_again() -> None:
    tracker = track(LIT_RED)
    # Both seen in the first frame are pieces of one seed, one model; the face, unassociated in
    # every frame after, is a double of it and gives no model either.
    assert tracker.ids == ["o1"]
    assert tracker.created_count == 1
    assert np.allclose(tracker.boxes[0], BODY, atol=1.0)


def test_an_object_in_another_hue_before_a_larger_one_keeps_its_anchor() -> None:
    tracker = track(BLUE)
    assert tracker.ids == ["o1", "o2"]
    assert tracker.created_count == 2


def test_a_double_of_a_model_missed_in_its_frame_is_taken_by_that_model() -> None:
    """The object's body seen, then in one frame only its lit face (the body's percept missed):
    the face is no new model (it would be deleted as a double the next frame the body is seen,
    and made again whenever the body is missed) but the body's model takes it."""
    tracker = AnchorTracker(PerceptionParams().anchors, 320, 200, Coding(BINS, joint=False))
    body = PerceptSet(np.array([BODY]), np.array([RED]), np.array([3000]), np.array([0]))
    face = PerceptSet(np.array([FACE]), np.array([LIT_RED]), np.array([800]), np.array([0]))
    for k, percepts in enumerate([body, body, face, body, face, body]):
        tracker.predict()
        anchors = tracker.update(percepts, still(), k / 15)
    assert [a.id for a in anchors] == ["o1"]
    assert tracker.created_count == 1


def grey(y: int) -> np.ndarray:
    """(3, BINS) of a grey of luminance ``y``: Cr and Cb spread over the two bins about 128,
    as a grey surface's noise spreads them (their mean is 128, no hue)."""
    return (histograms(y, 120, 120) + histograms(y, 136, 136)) / 2


BOTH = np.ones(2, bool)
"""Both would be seeds (anchors) by themselves."""
GREY_TOP = grey(190)
GREY_FOOT = grey(90)
"""A grey object's lit top and shaded foot: no hue either."""


def test_the_lit_top_and_shaded_foot_of_a_grey_object_cut_apart_by_a_band_are_one_seed() -> None:
    """The band between them as bright as the floor cut the foreground in two; 4 pixels apart,
    the top 22 high: one group, one anchor."""
    boxes = np.array([(220.0, 134.0, 28.0, 22.0), (213.0, 160.0, 51.0, 22.0)])
    assert pieces(boxes, np.array([GREY_TOP, GREY_FOOT]), BOTH).tolist() == [0, 0]
    tracker = AnchorTracker(PerceptionParams().anchors, 320, 200, Coding(BINS, joint=False))
    seeds = PerceptSet(
        boxes, np.array([GREY_TOP, GREY_FOOT]), np.array([400, 450]), np.array([4, 5])
    )
    tracker.predict()
    tracker.update(seeds, still(), 0.0)
    assert tracker.ids == ["o1"]
    assert np.allclose(tracker.boxes[0], (213.0, 134.0, 51.0, 48.0), atol=1.0)


def test_pieces_apart_in_another_hue_or_grey_beside_a_colour_or_far_apart_are_two() -> None:
    touching = np.array([(100.0, 80.0, 40.0, 40.0), (140.0, 80.0, 40.0, 40.0)])
    assert pieces(touching, np.array([RED, BLUE]), BOTH).tolist() == [0, 1]
    assert pieces(touching, np.array([GREY_TOP, RED]), BOTH).tolist() == [0, 1]
    assert pieces(touching, np.array([RED, LIT_RED]), BOTH).tolist() == [0, 0]
    apart = np.array([(100.0, 80.0, 40.0, 40.0), (160.0, 80.0, 40.0, 40.0)])  # 20 px: half
    assert pieces(apart, np.array([RED, LIT_RED]), BOTH).tolist() == [0, 1]
    assert pieces(touching, np.array([RED, LIT_RED]), np.array([True, False])).tolist() == [0, 1]
    chain = np.array([(0.0, 0.0, 10.0, 10.0), (12.0, 0.0, 10.0, 10.0), (24.0, 0.0, 10.0, 10.0)])
    assert pieces(chain, np.array([RED, LIT_RED, RED]), np.ones(3, bool)).tolist() == [0, 0, 0]
