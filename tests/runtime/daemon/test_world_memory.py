"""World models while the head turns away and back: the daemon's pipeline (forward kinematics of
the OP3's head, perception, features) on frames rendered from the poses of its joint angles
(:mod:`percept.perception.evaluation.cubes`). An object out of view stays in the world model,
not visible, with the features of its last sighting and the time of it; it comes back under its
id; the messages pass their own check and draw."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from percept.perception.evaluation.cubes import GREEN, RED, YELLOW, Cube, render
from percept.perception.features import experience as features
from percept.runtime.daemon.pipeline import FrameInputs, Pipeline
from percept.runtime.net.messages import World, WorldObject, decode, document, encode
from percept.runtime.record.drawing import draw_anchors, draw_map, object_bgr
from percept.runtime.settings.profile import load_profile
from tests.support.zenoh_rig import PROFILE, experiment

pytestmark = pytest.mark.timeout(60)

W, H = 176, 144
FPS = 10.0
WALL = 1.7e9
TILT = -0.7  # looking down
PANS = [0.0] * 20 + [-0.5, -1.0] + [-1.0] * 60 + [-0.5, 0.0] + [0.0] * 20
BACK = 84  # the first frame looking ahead again


WORLD_SEEN = World(
    "a",
    WALL,
    1,
    {"R": np.eye(3).tolist(), "t": [0.0, 0.0, 0.5]},
    (WorldObject("o1", (40.0, 30.0, 30.0, 30.0), {"x": 0.8, "y": 0.1}, last_seen=WALL),),
)


def _worlds() -> list[World]:
    pipeline = Pipeline("a", load_profile(PROFILE), experiment("a"), W, H, joint_max_age=0.1)
    rng = np.random.default_rng(2)
    cubes = [Cube(RED, 0.6, 0.0), Cube(GREEN, 0.5, 0.22), Cube(YELLOW, 0.45, -0.55)]
    ahead = pipeline.tree.camera_pose({"head_pan": 0.0, "head_tilt": TILT})
    pipeline.calibrate([render([], 0, pipeline.camera, ahead, rng)[0] for _ in range(30)])
    worlds = []
    for f, pan in enumerate(PANS):
        joints = {"head_pan": pan, "head_tilt": TILT}
        pose = pipeline.tree.camera_pose(joints)
        image, _ = render(cubes, f, pipeline.camera, pose, rng)
        inputs = FrameInputs(seq=f, t=f / FPS, wall=WALL + f / FPS, joints=joints)
        world = pipeline.step(image, inputs).world
        assert world is not None
        worlds.append(world)
    return worlds


def test_an_object_out_of_view_stays_in_the_world_model_and_comes_back() -> None:
    worlds = _worlds()
    seen = {o.id: o for o in worlds[19].objects}
    assert len(seen) == 2 and all(o.visible for o in seen.values())
    red = next(o for o in seen.values() if o.features["x"] > 0.55)  # type: ignore[operator]
    assert red.last_seen == pytest.approx(WALL + 1.9)
    away = {o.id: o for o in worlds[60].objects}
    assert set(seen) < set(away)  # both remembered, and the yellow cube seen over there
    remembered = away[red.id]
    assert not remembered.visible and remembered.last_seen == pytest.approx(WALL + 2.0, abs=0.1)
    # Its features are those of a sighting, its place about right; its box is off the image.
    sightings = [o.features for w in worlds[:25] for o in w.objects if o.id == red.id]
    assert remembered.features in sightings
    assert remembered.position == pytest.approx((0.6, 0.0), abs=0.02)
    assert remembered.bbox[0] + remembered.bbox[2] < 0
    message = json.loads(encode(worlds[60]))
    assert message["schema"] == "percept.world/2"
    assert decode(json.dumps(message).encode(), World.SCHEMA) == worlds[60]
    back = {o.id: o for o in worlds[-1].objects}
    assert back[red.id].visible and back[red.id].last_seen == pytest.approx(worlds[-1].stamp)
    assert document(worlds[-1])["objects"]  # type: ignore[index]


def test_remembered_objects_are_drawn_hollow() -> None:
    features = {"x": 0.8, "y": 0.1, "width": 0.3, "luminance": 80.0, "green_red": 200.0,
                "yellow_blue": 100.0}  # fmt: skip
    seen = World(
        "a", WALL, 1, {"R": np.eye(3).tolist(), "t": [0.0, 0.0, 0.5]},
        (WorldObject("o1", (40.0, 30.0, 30.0, 30.0), features),),
    )  # fmt: skip
    remembered = replace(
        seen, objects=(replace(seen.objects[0], visible=False, last_seen=WALL - 3),)
    )
    colour = np.array(object_bgr(features))

    def painted(image: np.ndarray) -> int:
        return int(np.all(image == colour, axis=2).sum())

    assert painted(draw_map(remembered)) < painted(draw_map(seen)) / 2 > 0
    assert painted(draw_map(remembered)) > 0
    camera = np.full((H, W, 3), 120, np.uint8)
    assert 0 < painted(draw_anchors(camera, remembered)) < painted(draw_anchors(camera, seen))


def test_a_replay_compares_with_version_1_recordings_in_their_schema() -> None:
    from percept.runtime.record.replay import ReplayReport, _compare

    replayed = document(WORLD_SEEN)
    old = json.loads(json.dumps(replayed))
    old["schema"] = "percept.world/1"
    for o in old["objects"]:
        del o["visible"], o["last_seen"]
    report = ReplayReport()
    _compare(1, {1: replayed}, {1: old}, report)
    assert report.matched == 1 and not report.differing
    moved = json.loads(json.dumps(old))
    moved["objects"][0]["bbox"][0] += 1
    _compare(2, {2: replayed}, {2: moved}, report)
    assert report.differing == [2]
    # A version 2 recording compares every field.
    remembered = json.loads(json.dumps(replayed))
    remembered["objects"][0]["visible"] = False
    _compare(3, {3: replayed}, {3: remembered}, report)
    assert report.differing == [2, 3]
    # Recorded before world models reported agents: none to compare, the rest as recorded.
    before_agents = json.loads(json.dumps(replayed))
    assert before_agents.pop("agents") == []
    _compare(4, {4: replayed}, {4: before_agents}, report)
    assert report.matched == 2 and report.differing == [2, 3]


def _still_worlds() -> tuple[list[World], int]:
    """World models of two cubes seen with the head still (noisy frames), and how many
    sensory experiences kept their last fit."""
    pipeline = Pipeline("a", load_profile(PROFILE), experiment("a"), W, H, joint_max_age=0.1)
    rng = np.random.default_rng(5)
    cubes = [Cube(RED, 0.6, 0.0), Cube(GREEN, 0.5, 0.22)]
    joints = {"head_pan": 0.0, "head_tilt": TILT}
    pose = pipeline.tree.camera_pose(joints)
    pipeline.calibrate([render([], 0, pipeline.camera, pose, rng)[0] for _ in range(30)])
    worlds = []
    for f in range(30):
        image, _ = render(cubes, f, pipeline.camera, pose, rng)
        inputs = FrameInputs(seq=f, t=f / FPS, wall=WALL + f / FPS, joints=joints)
        world = pipeline.step(image, inputs).world
        assert world is not None
        worlds.append(world)
    return worlds, pipeline.features.reused


def test_unchanged_anchors_keep_their_features_as_fitting_again_gives_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """With the head still most experiences keep their last fit (58 of 60 here), and the world
    models are those of fitting every anchor in every frame, to the bit."""
    kept, reused = _still_worlds()
    monkeypatch.setattr(features, "_same_sighting", lambda *_: False)  # every anchor fitted
    fitted, none = _still_worlds()
    assert none == 0 and reused >= 50
    assert [len(w.objects) for w in kept] == [2] * 30
    assert kept == fitted
