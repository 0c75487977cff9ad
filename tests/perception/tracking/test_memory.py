"""Anchors while the head turns: boxes carried into the new view, objects remembered out of view
and recognised when they come back, forgotten when their place is seen empty; on frames of cubes
on a uniform floor rendered from known poses (:mod:`percept.perception.evaluation.cubes`)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from percept.kinematics.camera import CameraModel
from percept.perception.evaluation.cubes import GREEN, RED, YELLOW, Cube, matched_id, render
from percept.perception.evaluation.cubes import head_pose as pose
from percept.perception.evaluation.synthetic import busy_scene
from percept.perception.params import PerceptionParams
from percept.perception.pipeline import STALE_HOLD, FrameResult, Perception
from percept.perception.tracking.anchors import Anchor
from percept.perception.tracking.kalman import BoxFilters
from percept.perception.tracking.permanence.memory import AnchorMemory, Remembered, Sighting

pytestmark = pytest.mark.timeout(60)

W, H = 176, 144
FPS = 10.0
CAMERA = CameraModel.from_opening_angles(math.radians(60), math.radians(47), W, H)


def run(
    cubes: list[Cube],
    pans: list[float],
    with_poses: bool = True,
    params=None,
    given: list[float] | None = None,
    fresh: list[bool] | None = None,
    before: Callable[[int, Perception], None] | None = None,
):
    """Calibrate on the empty floor, then process one frame per pan angle; the results and
    each frame's boxes of the cubes. The poses are given at the pans ``given`` (default: the
    true ones), marked ``fresh`` or not (default: all are); ``before(f, perception)`` is called
    before frame ``f``."""
    rng = np.random.default_rng(1)
    perception = Perception(params or PerceptionParams(), W, H, CAMERA)
    perception.calibrate([render([], 0, CAMERA, pose(0.0), rng)[0] for _ in range(30)])
    results, truth = [], []
    for f, pan in enumerate(pans):
        if before is not None:
            before(f, perception)
        image, boxes = render(cubes, f, CAMERA, pose(pan), rng)
        at = pose(pan if given is None else given[f]) if with_poses else None
        up_to_date = True if fresh is None else fresh[f]
        results.append(perception.process(image, f / FPS, at, pose_fresh=up_to_date))
        truth.append(boxes)
    return perception, results, truth


def ids(results, truth, cube: int, frames) -> set[str | None]:
    return {matched_id(results[f].anchors, truth[f][cube]) for f in frames}


def anchor(result: FrameResult, anchor_id: str) -> Anchor | None:
    return next((a for a in result.anchors if a.id == anchor_id), None)


def test_an_object_keeps_its_anchor_across_a_quick_head_turn() -> None:
    cubes = [Cube(RED, 0.65, 0.2), Cube(GREEN, 0.55, 0.02)]
    pans = [0.0] * 20 + [0.35] * 20  # a saccade: 0.35 rad (about 50 pixels) in one frame
    perception, results, truth = run(cubes, pans)
    assert ids(results, truth, 0, range(5, 40)) == {"o1"}
    assert ids(results, truth, 1, range(5, 40)) == {"o2"}
    assert perception.tracker.created_count == 2
    # Without the poses the same frames make new anchors: the jump is beyond the gates.
    blind, results, truth = run(cubes, pans, with_poses=False)
    assert blind.tracker.created_count > 2
    assert len(ids(results, truth, 0, range(25, 40))) == 1
    assert ids(results, truth, 0, range(25, 40)) != {"o1"}


def test_warp_carries_a_box_with_the_view() -> None:
    """A box on the floor, moved by a pan: its foot lands where the floor point goes and its
    rate turns with the view, not absorbing the head's motion."""
    from percept.kinematics.ground import view_homography

    filters = BoxFilters(0.01, 1.0, 1.0, 1.0)
    filters.add(np.array([[80.0, 100.0, 20.0, 30.0]]))
    filters.x[0, 4:6] = (2.0, 0.0)
    before, after = pose(0.0), pose(0.1)
    Hm = view_homography(CAMERA.K, before, after)
    foot = Hm @ np.array([80.0, 115.0, 1.0])
    filters.warp(Hm)
    x, y, w, h, dx, dy = filters.x[0, :6]
    assert (x, y + h / 2) == pytest.approx(tuple(foot[:2] / foot[2]), abs=1e-9)
    assert w == pytest.approx(20.0, rel=0.05) and h == pytest.approx(30.0, rel=0.05)
    assert math.hypot(dx, dy) == pytest.approx(2.0, rel=0.05)
    assert x > 80.0 + 10  # a turn to the left moves what is seen to the right


def test_a_box_comes_into_view_only_at_the_border_the_turn_brings_in() -> None:
    """A turn to the left moves what is seen to the right: a box at the left border is coming
    into view, one at the right border is leaving it, one inside is neither."""
    from percept.kinematics.ground import view_homography
    from percept.perception.tracking.anchors import coming_into_view

    Hm = view_homography(CAMERA.K, pose(0.0), pose(0.05))
    w, h = CAMERA.width, CAMERA.height
    boxes = np.array([[0.0, 60.0, 12.0, 20.0], [w - 12.0, 60.0, 12.0, 20.0], [60, 60, 12, 20]])
    assert coming_into_view(boxes, Hm, w, h).tolist() == [True, False, False]
    assert not coming_into_view(boxes, np.eye(3), w, h).any()  # no turn: nothing comes in


AWAY = [0.0] * 20 + [-0.5, -1.0] + [-1.0] * 100 + [-0.5, 0.0] + [0.0] * 30
BACK = 124  # the first frame looking ahead again


def _away(red: Cube) -> tuple[Perception, list[FrameResult], list]:
    cubes = [red, Cube(GREEN, 0.5, 0.22), Cube(YELLOW, 0.45, -0.55)]
    return run(cubes, AWAY)


def test_box_shares_are_numpys() -> None:
    # The compiled shares against the numpy arithmetic they replace, to the bit: boxes that
    # overlap, touch, lie apart, one inside another, of no area, and no boxes at all.
    from percept.perception.tracking.permanence.memory import (
        covered,
        hidden_fraction,
        inside_fraction,
    )

    def by_numpy(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        w = np.minimum(a[:, 0:1] + a[:, 2:3], b[:, 0] + b[:, 2]) - np.maximum(a[:, 0:1], b[:, 0])
        h = np.minimum(a[:, 1:2] + a[:, 3:4], b[:, 1] + b[:, 3]) - np.maximum(a[:, 1:2], b[:, 1])
        area = np.maximum(a[:, 2:3] * a[:, 3:4], 1e-9)
        return np.clip(w, 0, None) * np.clip(h, 0, None) / area

    rng = np.random.default_rng(3)
    boxes = np.column_stack([rng.uniform(-20, W, (40, 2)), rng.uniform(0, 60, (40, 2))])
    boxes[:4] = [[10, 10, 20, 20], [30, 10, 20, 20], [15, 15, 5, 5], [50, 50, 0, 10]]
    shares = covered(boxes, boxes[::3])
    assert np.array_equal(shares, by_numpy(boxes, boxes[::3]))
    assert (shares == 0).any() and (shares == 1).any() and ((shares > 0) & (shares < 1)).any()
    image = np.array([[-0.5, -0.5, W, H]])
    assert np.array_equal(inside_fraction(boxes, W, H), by_numpy(boxes, image)[:, 0])
    seen = boxes[::2]
    nearer = seen[None, :, 1] + seen[None, :, 3] > boxes[:, 1:2] + boxes[:, 3:4]
    expected = np.where(nearer, by_numpy(boxes, seen), 0.0).max(axis=1)
    hidden = hidden_fraction(boxes, seen)
    assert np.array_equal(hidden, expected) and (hidden > 0).any() and (hidden == 0).any()
    assert np.array_equal(hidden_fraction(boxes, np.zeros((0, 4))), np.zeros(len(boxes)))
    assert covered(np.zeros((0, 4)), boxes).shape == (0, len(boxes))


def test_how_boxes_were_seen_is_numpys() -> None:
    # The compiled sorting of the anchors' boxes in AnchorMemory.follow against the numpy
    # expressions it replaces: seen whole, roughly, cut, and out of sight; boxes beyond the
    # border and half inside it, hidden in part and whole, seen and not, cut and not.
    from percept.perception.tracking.permanence.memory import (
        TOUCHING,
        hidden_fraction,
        inside_fraction,
    )
    from percept.perception.tracking.permanence.memory_kernels import sight

    rng = np.random.default_rng(8)
    limit = PerceptionParams().anchors.out_of_sight
    met = np.zeros(4, int)
    for n in (0, 1, 2, 5, 12, 30):
        for _ in range(20):
            boxes = np.column_stack([rng.uniform(-40, W, (n, 2)), rng.uniform(2, 60, (n, 2))])
            boxes[:2] = np.array([[-10.5, 10, 20, 10], [W - 10.5, 30, 20, 10]])[:n]  # half in
            seen, cut = rng.random(n) < 0.7, rng.random(n) < 0.3
            inside = inside_fraction(boxes, W, H)
            hidden = hidden_fraction(boxes, boxes[seen])
            whole = seen & ~cut & (hidden < TOUCHING)
            rough = seen & ~cut & ~whole & (hidden < limit)
            glimpsed = seen & cut & (hidden < limit)
            away = (inside < limit) | (hidden >= limit)
            got = sight(boxes, seen, cut, W, H, TOUCHING, limit)
            for g, expected in zip(got, (whole, rough, glimpsed, away), strict=True):
                assert g.dtype == bool and np.array_equal(g, expected)
            met += [k.sum() for k in got]
    assert (met > 10).all()


def test_feet_on_ground_and_reaches_are_numpys() -> None:
    # The compiled feet and distances against the numpy arithmetic they replace, to the bit:
    # boxes across the whole image and beyond it (feet above the horizon, farther than
    # MAX_DISTANCE, on the ground), heads pitched up and down, a camera at or below the ground,
    # and a distorted lens.
    from percept.kinematics.ground import ground_points
    from percept.kinematics.pose import CameraPose, rpy_matrix
    from percept.perception.tracking.permanence.memory import _centre, feet_on_ground
    from percept.perception.tracking.permanence.memory_kernels import reaches

    def by_numpy(camera: CameraModel, pose: CameraPose, boxes: np.ndarray):
        left, top, w, h = boxes.T
        feet = np.column_stack([((left - 0.5) + (left + w - 0.5)) / 2, top + h - 0.5])
        return ground_points(pose, camera.pixel_rays(feet))

    rng = np.random.default_rng(5)
    distorted = CameraModel(CAMERA.K, np.array([-0.3, 0.1, 0.001, -0.002, 0.0]), W, H)
    counts = np.zeros(2, int)
    for trial in range(300):
        camera = distorted if trial % 10 == 0 else CAMERA
        n = int(rng.integers(camera is distorted, 12))  # OpenCV cannot undistort no points
        boxes = np.column_stack([rng.uniform(-40, W + 40, (n, 2)), rng.uniform(0, 90, (n, 2))])
        height = 0.0 if trial % 25 == 0 else rng.uniform(-0.2, 1.0)
        R = rpy_matrix((0.0, rng.uniform(-0.6, 0.9), rng.uniform(-3.0, 3.0)))
        pose = CameraPose(R=R, t=np.array([*rng.uniform(-2.0, 2.0, 2), height]))
        xy, valid = feet_on_ground(camera, pose, boxes)
        expected_xy, expected_valid = by_numpy(camera, pose, boxes)
        assert np.array_equal(xy, expected_xy) and np.array_equal(valid, expected_valid)
        assert xy.shape == (n, 2) and valid.dtype == bool
        counts += valid.sum(), (~valid).sum()
        xy[rng.random(n) < 0.2] = np.nan
        expected = np.linalg.norm(np.column_stack([xy, np.zeros(n)]) - pose.t, axis=1)
        assert np.array_equal(reaches(xy, _centre(pose)), expected, equal_nan=True)
    assert (counts > 100).all()  # many feet on the ground and many not
    assert feet_on_ground(distorted, pose, np.zeros((0, 4)))[0].shape == (0, 2)


def test_an_object_out_of_view_for_ten_seconds_comes_back_with_its_id() -> None:
    perception, results, truth = _away(Cube(RED, 0.6, 0.0))
    assert ids(results, truth, 0, range(5, 20)) == {"o1"}
    assert ids(results, truth, 1, range(5, 20)) == {"o2"}
    # Away: remembered, not visible, last seen before the turn.
    for f in (40, 80, 120):
        red = anchor(results[f], "o1")
        assert red is not None and red.remembered and not red.visible
        assert red.last_seen < 2.2
    assert anchor(results[40], "o2").remembered
    assert ids(results, truth, 0, range(BACK + 3, len(AWAY))) == {"o1"}
    assert ids(results, truth, 1, range(BACK + 3, len(AWAY))) == {"o2"}
    assert perception.tracker.created_count == 3  # red, green, and yellow over there


def test_an_object_that_comes_back_touching_a_new_one_keeps_its_id() -> None:
    """Put down beside the red cube while the robot looked away, the green one makes one
    foreground region with it when the robot looks back: the remembered red anchor's colour
    cuts its part out (the split), the memory recognises it, and green gets an anchor of its
    own."""
    cubes = [Cube(RED, 0.6, 0.0), Cube(GREEN, 0.6, 0.1, start=60), Cube(YELLOW, 0.45, -0.55)]
    perception, results, truth = run(cubes, AWAY)
    assert ids(results, truth, 0, range(5, 20)) == {"o1"}
    assert anchor(results[100], "o1").remembered
    assert ids(results, truth, 0, range(BACK + 3, len(AWAY))) == {"o1"}
    green = ids(results, truth, 1, range(BACK + 3, len(AWAY)))
    assert len(green) == 1 and None not in green and "o1" not in green
    assert perception.tracker.created_count == 3  # red, yellow over there, and green


def test_an_object_never_seen_whole_is_remembered_too() -> None:
    """The red cube, put down behind the green one, is partly hidden by it in every frame: it
    is never seen whole, yet it is remembered when the robot looks away and keeps its id."""
    cubes = [Cube(RED, 0.62, 0.0, start=8), Cube(GREEN, 0.48, 0.06), Cube(YELLOW, 0.45, -0.55)]
    perception, results, truth = run(cubes, AWAY)
    assert ids(results, truth, 0, range(12, 20)) == {"o2"}
    assert anchor(results[100], "o2").remembered
    assert ids(results, truth, 0, range(BACK + 3, len(AWAY))) == {"o2"}
    assert ids(results, truth, 1, range(BACK + 3, len(AWAY))) == {"o1"}
    assert perception.tracker.created_count == 3


def test_an_anchor_carried_off_its_object_takes_it_back() -> None:
    """A filter carried off its still object (as a warp by a pose that lagged a head turn does:
    the box jumps and its rates run on) loses it; the object's pixels then make a seed where
    the anchor was last seen whole, in its colour, and the anchor takes it back: one anchor, its
    id kept. Without that rule the seed is a second anchor on the object."""
    cubes = [Cube(RED, 0.65, 0.1), Cube(GREEN, 0.55, -0.1)]

    def carry_off(f: int, perception: Perception) -> None:
        if f == 20:
            perception.tracker.filters.x[0, 0] += 60.0  # pixels: far beyond the gates
            perception.tracker.filters.x[0, 4] = 6.0

    perception, results, truth = run(cubes, [0.0] * 40, before=carry_off)
    assert ids(results, truth, 0, range(5, 40)) == {"o1"}
    assert ids(results, truth, 1, range(5, 40)) == {"o2"}
    assert perception.tracker.created_count == 2


def _late(flagged: bool) -> tuple[Perception, list[FrameResult], list]:
    """The head turns 0.36 rad in six frames while the joint readings lag: each of those
    frames comes with the pose from before the turn, marked not fresh when ``flagged``."""
    cubes = [Cube(RED, 0.65, 0.1), Cube(GREEN, 0.55, -0.05)]
    pans = [0.0] * 20 + [0.06 * (k + 1) for k in range(6)] + [0.36] * 30
    given = [0.0] * 26 + [0.36] * 30
    fresh = [not (flagged and pan != at) for pan, at in zip(pans, given, strict=True)]
    return run(cubes, pans, given=given, fresh=fresh)


def test_frames_whose_pose_is_not_fresh_leave_the_anchors_as_they_stand() -> None:
    """While the pose lags the turn, the background is brought into the wrong view; the anchors
    stand until a fresh pose comes, which carries them into the new view: no anchor is made on
    the floor or a second one on an object. Taken as fresh, the same frames make new ones."""
    perception, results, truth = _late(flagged=True)
    assert perception.tracker.created_count == 2
    assert ids(results, truth, 0, range(30, 56)) == {"o1"}
    standing = [(a.id, a.bbox) for a in results[19].anchors]
    assert all([(a.id, a.bbox) for a in results[f].anchors] == standing for f in range(20, 26))
    unflagged, _, _ = _late(flagged=False)
    assert unflagged.tracker.created_count > 2


def test_a_joint_that_stopped_answering_does_not_stop_the_anchors() -> None:
    """A joint of the camera's chain stops answering with the head still: every pose from then
    on is not fresh. After ``STALE_HOLD`` the frames are taken as they come, and an object put
    down then gets its anchor."""
    cubes = [Cube(RED, 0.65, 0.1), Cube(GREEN, 0.55, -0.05, start=40)]
    _, results, truth = run(cubes, [0.0] * 70, fresh=[f < 20 for f in range(70)])
    assert STALE_HOLD * FPS < 40 - 20
    assert ids(results, truth, 0, range(5, 70)) == {"o1"}
    assert ids(results, truth, 1, range(50, 70)) == {"o2"}


def test_a_remembered_anchor_whose_object_was_anchored_again_is_forgotten() -> None:
    """An anchor seen where a remembered one of its colour stood is that object anchored again
    (made before the old anchor left the tracker): the remembered one is forgotten, or it would
    come back as a second anchor on the object. One of another colour, or farther than
    ``reacquire_distance``, is another object and stays remembered."""
    params = PerceptionParams().anchors
    red = np.zeros((3, 8))
    red[:, 2] = 1.0
    green = np.zeros((3, 8))
    green[:, 6] = 1.0

    def remembered(anchor_id: str, x: float, histograms: np.ndarray) -> Remembered:
        sighting = Sighting(np.array([x, 0.0]), (20.0, 20.0), x)
        return Remembered(anchor_id, sighting, histograms, 0.0, 1.0, 400, (0, 0, 20, 20))

    memory = AnchorMemory(params, CAMERA, W, H)
    for r in (
        remembered("o1", 0.60, red),
        remembered("o2", 0.61, green),
        remembered("o3", 0.60 + 2 * params.reacquire_distance, red),
    ):
        memory.keep(r)
    memory.sightings["o9"] = Sighting(np.array([0.63, 0.0]), (20.0, 20.0), 0.63)
    memory.forget_doubles(["o9"], red[None])
    assert sorted(memory.remembered) == ["o2", "o3"]


def test_an_object_only_ever_seen_cut_by_the_border_comes_back_with_its_id() -> None:
    """The red cube stands so near that the image's bottom cuts it in every frame: its foot is
    never seen, so it has no place on the ground. It is remembered by its glimpse (its box's
    corners as directions) and recognised by its box when the robot looks back."""
    perception, results, _ = run([Cube(RED, 0.2, 0.0), Cube(GREEN, 0.5, 0.22)], AWAY)
    red = anchor(results[15], "o2")
    assert red is not None and red.bbox[1] + red.bbox[3] > H - 2  # cut by the bottom
    assert anchor(results[80], "o2").remembered
    back = anchor(results[-1], "o2")
    assert back is not None and back.visible
    assert perception.tracker.created_count == 2


def test_an_object_put_down_against_another_while_the_head_pans_gets_its_anchor() -> None:
    """The head never stops; the green cube is put down against the red one: one foreground
    region, which red's model takes. Green is neither in red's colours nor inside its box, so it
    gets an anchor of its own (no new anchor there would wait for a head that never holds)."""
    pans = [0.0] * 20 + [0.004 * k for k in range(80)]
    cubes = [Cube(RED, 0.6, 0.0), Cube(GREEN, 0.6, -0.1, start=30)]
    perception, results, truth = run(cubes, pans)
    assert ids(results, truth, 0, range(5, 100)) == {"o1"}
    assert ids(results, truth, 1, range(50, 100)) == {"o2"}
    assert perception.tracker.created_count == 2


def test_an_object_put_down_behind_another_in_another_hue_while_the_head_pans_gets_its_anchor() -> (
    None
):
    """The head never stops; the green cube is put down right behind the red one: one
    foreground region, which red's model takes, and green's box lies partly in red's. Its hue is
    not red's, so it is another object, not a face of red's in another shade: its own anchor
    (of the part of it seen above red)."""
    pans = [0.0] * 20 + [0.004 * k for k in range(80)]
    cubes = [Cube(RED, 0.6, 0.0), Cube(GREEN, 0.68, 0.0, start=30)]
    perception, results, truth = run(cubes, pans)
    assert ids(results, truth, 0, range(5, 100)) == {"o1"}
    for f in range(50, 100):
        green = anchor(results[f], "o2")
        assert green is not None and green.visible
        left, top, w, _ = truth[f][1]
        x, y = green.bbox[0] + green.bbox[2] / 2, green.bbox[1] + green.bbox[3] / 2
        assert left <= x <= left + w and top <= y <= truth[f][0][1]  # above red's top
    assert perception.tracker.created_count == 2


def test_an_object_moved_a_little_while_out_of_view_keeps_its_id() -> None:
    red = Cube(RED, 0.6, 0.0, moved_at=60, moved=(0.05, -0.06))
    perception, results, truth = _away(red)
    assert ids(results, truth, 0, range(BACK + 3, len(AWAY))) == {"o1"}
    assert perception.tracker.created_count == 3


def test_an_object_taken_away_out_of_view_is_forgotten_once_its_place_is_seen() -> None:
    _, results, truth = _away(Cube(RED, 0.6, 0.0, stop=60))
    assert anchor(results[100], "o1").remembered
    assert anchor(results[BACK + 3], "o1") is not None  # not at once: its place may be hidden
    gone = [f for f in range(BACK, len(AWAY)) if anchor(results[f], "o1") is None]
    assert gone and gone[0] <= BACK + 15 and gone == list(range(gone[0], len(AWAY)))
    assert ids(results, truth, 1, range(BACK + 3, len(AWAY))) == {"o2"}


def test_memory_lasts_memory_seconds() -> None:
    from dataclasses import replace

    params = PerceptionParams()
    params = replace(params, anchors=replace(params.anchors, memory=5.0))
    cubes = [Cube(RED, 0.6, 0.0), Cube(GREEN, 0.5, 0.22), Cube(YELLOW, 0.45, -0.55)]
    _, results, truth = run(cubes, AWAY, params=params)
    assert anchor(results[60], "o1") is not None
    assert anchor(results[80], "o1") is None  # last seen at 2.0 s, forgotten after 7 s
    assert ids(results, truth, 0, range(BACK + 3, len(AWAY))) == {"o4"}


def test_a_still_head_gives_the_same_anchors() -> None:
    """With a pose that never changes (and nothing out of sight for max_absence), the anchors
    are those of a still camera, to the last bit."""
    scene = busy_scene(W, H, 120)
    results = {}
    for name, at in (("still", None), ("posed", pose(0.0))):
        perception = Perception(PerceptionParams(), W, H, CAMERA)
        perception.calibrate(scene.empty(30))
        results[name] = [perception.process(scene.render(f), f / 25, at) for f in range(120)]
    for still, posed in zip(results["still"], results["posed"], strict=True):
        key = [(a.id, a.bbox, a.last_seen) for a in still.anchors]
        assert [(a.id, a.bbox, a.last_seen) for a in posed.anchors if not a.remembered] == key


HIDING = [0.0] * 100
TALL = Cube(GREEN, 0.42, 0.0, side=0.12, height=0.35, start=20, stop=60)  # hides the red cube


def test_an_object_hidden_behind_a_nearer_one_is_remembered_and_comes_back() -> None:
    perception, results, truth = run([Cube(RED, 0.7, 0.0), TALL], HIDING)
    assert ids(results, truth, 0, range(5, 20)) == {"o1"}
    for f in (40, 55):  # unseen for longer than max_absence, and not forgotten
        red = anchor(results[f], "o1")
        assert red is not None and red.remembered and not red.visible
    assert all(anchor(results[f], "o2").visible for f in range(25, 60))  # the tall one
    assert ids(results, truth, 0, range(63, 100)) == {"o1"}
    assert perception.tracker.created_count == 2
    # A still camera without a pose forgets it after max_absence: a new anchor.
    _, results, truth = run([Cube(RED, 0.7, 0.0), TALL], HIDING, with_poses=False)
    assert ids(results, truth, 0, range(63, 100)) == {"o3"}


def test_an_object_taken_away_while_hidden_is_forgotten_once_its_place_is_seen() -> None:
    _, results, _ = run([Cube(RED, 0.7, 0.0, stop=40), TALL], HIDING)
    assert anchor(results[55], "o1").remembered
    gone = [f for f in range(60, 100) if anchor(results[f], "o1") is None]
    assert gone and gone[0] <= 75 and gone == list(range(gone[0], 100))
