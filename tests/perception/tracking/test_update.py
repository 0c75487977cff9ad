"""The anchors' update of a frame in one compiled call (:func:`track`): the same results as its
kernels called one by one, and ``steady`` only when Python has nothing left to do."""

from __future__ import annotations

import numpy as np
import pytest

from percept.perception.tracking.anchors import DOUBLE
from percept.perception.tracking.anchors_kernels import correct, may_double
from percept.perception.tracking.association_kernels import best_models
from percept.perception.tracking.kalman import BoxFilters
from percept.perception.tracking.motion_kernels import MOST, moved_in_boxes
from percept.perception.tracking.permanence.memory import covered
from percept.perception.tracking.update_kernels import track

W, H, M = 176, 144, 16
T_SPACE, T_COLOR = np.array([0.7, 0.5]), np.array([0.5, 0.3])
DIAGONAL = float(np.hypot(W, H))


def histograms(rng: np.random.Generator, n: int) -> np.ndarray:
    h = rng.random((n, 3, M)) ** 3
    return h / h.sum(axis=-1, keepdims=True)


def frame(seed: int) -> dict[str, object]:
    """Models, percepts near them (some of no model), two frames with changes and the times;
    seed 3 has a model unseen for long, seed 4 two still models one inside the other."""
    rng = np.random.default_rng(seed)
    n, step = 6, 1 + seed % 2
    filters = BoxFilters(0.01, 1.0, 1.0, 1.0)
    centres = rng.uniform([20, 20], [W - 20, H - 20], (n, 2))
    filters.add(np.column_stack([centres, rng.uniform(6, 20, (n, 2))]))
    if seed == 4:  # model 1 inside model 0, both seen and still
        filters.x[1, :2], filters.x[1, 2:4] = filters.x[0, :2], filters.x[0, 2:4] * 0.8
    models = histograms(rng, n)
    k = n + (seed % 3 == 0)
    which = np.arange(k) % n
    jitter = rng.normal(0, 1.5, (k, 4))
    boxes = filters.boxes[which] + jitter
    percepts = models[which] * 0.9 + histograms(rng, k) * 0.1
    percepts /= percepts.sum(axis=-1, keepdims=True)
    if seed % 3 == 0:  # a percept far from every model, in colours of none
        boxes[-1] = (2.0, 2.0, 5.0, 5.0)
        percepts[-1] = histograms(rng, 1)[0]
    grid = (H // step, W // step, 3)
    current = rng.integers(0, 256, grid, dtype=np.uint8)
    previous = current.copy()
    changed = rng.random(grid[:2]) < 0.02
    previous[changed] = 255 - previous[changed]
    last_seen = np.full(n, 1.9)
    if seed == 3:
        last_seen[2] = 0.1
    return {
        "step": step,
        "frames": (current, previous, rng.integers(0, 30, grid, dtype=np.uint8)),
        "filters": filters,
        "models": models,
        "percepts": (boxes, percepts, rng.integers(20, 400, k), which),
        "last_seen": last_seen,
        "pixels": rng.integers(20, 400, n),
    }


def run(f: dict, count: bool, in_motion: np.ndarray, max_absence: float = 1.0) -> tuple:
    filters = f["filters"]
    current, previous, upper = f["frames"]
    return track(
        *(current, previous, upper, 3, f["step"], count, in_motion),
        *f["percepts"],
        *(filters.x, filters.cov, filters.r, f["models"], T_SPACE, T_COLOR, DIAGONAL, 0.1),
        *(f["last_seen"], f["pixels"], 2.0, W, H, False, max_absence, DOUBLE),
    )


@pytest.mark.parametrize("seed", range(6))
def test_one_call_is_the_motion_association_and_correction_one_by_one(seed: int) -> None:
    mine, theirs = frame(seed), frame(seed)
    answered, moving, best, models, cut, steady = run(mine, True, np.zeros(0, bool))
    assert answered

    filters = theirs["filters"]
    current, previous, upper = theirs["frames"]
    grid = filters.boxes / theirs["step"] if theirs["step"] > 1 else filters.boxes
    expected_moving = moved_in_boxes(current, previous, upper, grid, 3, MOST) > 0
    boxes, hist, counts, regions = theirs["percepts"]
    expected_best = best_models(
        boxes, hist, filters.x, theirs["models"], expected_moving, T_SPACE, T_COLOR, DIAGONAL
    )
    last_seen, pixels = theirs["last_seen"], theirs["pixels"]
    expected = correct(
        *(expected_best, boxes, hist, counts, regions, filters.x, filters.cov, filters.r),
        *(theirs["models"], 0.1, last_seen, pixels, 2.0, W, H, False),
    )
    np.testing.assert_array_equal(moving, expected_moving)
    np.testing.assert_array_equal(best, expected_best)
    np.testing.assert_array_equal(models, expected[0])
    np.testing.assert_array_equal(cut, expected[1])
    for a, b in ((mine["filters"].x, filters.x), (mine["filters"].cov, filters.cov)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(mine["last_seen"], last_seen)
    np.testing.assert_array_equal(mine["pixels"], pixels)

    # Steady: every percept a model's, every model seen within the absence, no two doubles.
    seen = np.flatnonzero((last_seen == 2.0) & ~expected_moving)
    inside = covered(filters.boxes[seen], filters.boxes[seen])
    pairs = np.maximum(inside, inside.T) >= DOUBLE
    np.fill_diagonal(pairs, False)
    alive = (2.0 - last_seen <= 1.0).all()
    assert steady == ((expected_best >= 0).all() and alive and not pairs.any())
    assert steady == (seed in (1, 2, 5)), "each seed is made to be steady or not"


def test_boxes_that_read_much_of_the_image_are_left_to_the_caller() -> None:
    # The compiled count answers for at most a quarter of the image: beyond, nothing changes
    # and the caller counts on the whole mask, then calls with the motion given.
    f = frame(1)
    f["filters"].x[:, 2:4] = 120.0
    before = [np.copy(a) for a in (f["filters"].x, f["filters"].cov, f["last_seen"])]
    answered, *_ = run(f, True, np.zeros(0, bool))
    assert not answered
    for a, b in zip((f["filters"].x, f["filters"].cov, f["last_seen"]), before, strict=True):
        np.testing.assert_array_equal(a, b)
    given = np.arange(6) % 2 == 0
    answered, moving, *_ = run(f, False, given)
    assert answered and np.array_equal(moving, given)
    assert (f["last_seen"] == 2.0).any()


def test_may_double_is_the_overlap_test_of_the_doubles() -> None:
    rng = np.random.default_rng(3)
    hits = 0
    for _ in range(300):
        n = int(rng.integers(0, 6))
        boxes = np.column_stack([rng.uniform(0, 60, (n, 2)), rng.uniform(1, 30, (n, 2))])
        rows = np.flatnonzero(rng.random(n) < 0.7)
        inside = covered(boxes[rows], boxes[rows])
        pairs = np.maximum(inside, inside.T) >= DOUBLE
        np.fill_diagonal(pairs, False)
        assert may_double(boxes, rows, DOUBLE) == pairs.any()
        hits += pairs.any()
    assert 10 < hits < 290
