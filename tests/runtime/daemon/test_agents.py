"""People are not objects: a simulated person walks up to the table and stands beside it for
20 s, another walks through behind the objects. The daemon's pipeline (forward kinematics,
perception, features) on frames rendered by the simulated world reports the person under the
world model's ``agents`` and never among its ``objects``; the three objects stay objects. The
rules themselves (:class:`~percept.perception.features.agents.AgentJudge`) on made-up anchors."""

from __future__ import annotations

import json
from dataclasses import dataclass, replace

import numpy as np
import pytest

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose
from percept.kinematics.tree import KinematicTree
from percept.perception.features.agents import AgentJudge
from percept.perception.pipeline import Perception
from percept.perception.segmentation.percepts import PerceptSet
from percept.perception.tracking.anchors import Anchor, snapshot
from percept.perception.tracking.motion import Motion
from percept.perception.tracking.permanence.memory import covered
from percept.runtime.commands.offline.track import Agents, track_frames
from percept.runtime.daemon.pipeline import FrameInputs, Pipeline
from percept.runtime.net.messages import MessageError, World, decode, encode
from percept.runtime.settings.profile import load_profile
from percept.runtime.settings.scene import open_world
from tests.support.zenoh_rig import PROFILE, experiment

FPS = 5.0
WALL = 1.7e9
ROBOT_X = -0.72  # the robot's place in the scene; it faces +x, so its ground frame is shifted
STANDS = (0.35, -0.4)  # where the person stands, 20 s from t = 2.5
PEOPLE = (11, 12)  # the stander's and the walker's ids

SCENE = """name = "people"
description = "three objects; a person stands beside the table for 20 s, another walks through"
seed = 5
duration = 24.0

[camera]
noise = 1.5

[floor]
texture = "wood"
color = [196, 164, 124]
size = [6.0, 6.0]
tile = 0.6

[lighting]
ambient = [0.45, 0.45, 0.45]

[[lighting.lights]]
direction = [0.3, 0.2, -1.0]
diffuse = [0.6, 0.6, 0.6]

[[robots]]
name = "a"
profile = "{profile}"
pose = [-0.72, 0.0, 0.0]
joints.head_tilt = { offset = -0.5 }

[[objects]]
id = 1
name = "red-block"
shape = "block"
size = [0.04, 0.04, 0.10]
color = [200, 30, 35]
pose = [0.0, 0.0, 0.3]
present = false

[[objects]]
id = 2
name = "blue-cylinder"
shape = "cylinder"
size = [0.055, 0.055, 0.07]
color = [30, 70, 200]
pose = [0.12, -0.1, 0.0]
present = false

[[objects]]
id = 3
name = "yellow-cone"
shape = "cone"
size = [0.06, 0.06, 0.08]
color = [230, 200, 20]
pose = [-0.1, 0.12, 0.0]
present = false

[[objects]]
id = 11
name = "stander"
shape = "figure"
size = [0.34, 0.34, 1.75]
color = [150, 60, 50]
pose = [0.5, -1.2, 0.0]
present = false

[[objects]]
id = 12
name = "walker"
shape = "figure"
size = [0.32, 0.32, 1.7]
color = [70, 80, 110]
pose = [0.45, 1.6, 0.0]
present = false

[[timeline]]
t = 0.5
action = "add"
object = 1

[[timeline]]
t = 0.5
action = "add"
object = 2

[[timeline]]
t = 0.5
action = "add"
object = 3

[[timeline]]
t = 1.0
action = "add"
object = 11

[[timeline]]
t = 1.0
action = "move"
object = 11
path = [[0.35, -0.4]]
duration = 1.5

[[timeline]]
t = 21.0
action = "move"
object = 11
path = [[0.5, -1.6]]
duration = 1.5

[[timeline]]
t = 5.0
action = "add"
object = 12

[[timeline]]
t = 5.0
action = "move"
object = 12
path = [[0.45, -1.6]]
duration = 3.0
"""


@dataclass(frozen=True)
class Rendered:
    """The scene as robot ``a`` saw it: empty frames for the calibration, then each frame's
    time, image, joint angles and the people's true boxes in it."""

    empty: list[np.ndarray]
    frames: list[tuple[float, np.ndarray, dict[str, float], list[tuple[float, ...]]]]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> Rendered:
    path = tmp_path_factory.mktemp("people") / "people.toml"
    path.write_text(SCENE.replace("{profile}", str(PROFILE)), encoding="utf-8")
    world = open_world(path)
    try:
        empty = [
            world.render("a", 0.0)
            for _ in range(experiment("a").perception.background.calibration_frames)
        ]
        frames = []
        for k in range(round(24.0 * FPS)):
            t = 0.2 + k / FPS
            view = world.truth(t, ["a"]).views["a"].objects
            people = [tuple(view[i].bbox) for i in PEOPLE if i in view and view[i].bbox]
            frames.append((t, world.render("a", t), world.joint_angles("a", t), people))
        return Rendered(empty, frames)
    finally:
        world.close()


@pytest.fixture(scope="module")
def worlds(rendered: Rendered) -> list[World]:
    height, width = rendered.empty[0].shape[:2]
    pipeline = Pipeline("a", load_profile(PROFILE), experiment("a"), width, height, 0.1)
    pipeline.calibrate(rendered.empty)
    out = []
    for k, (t, image, joints, _) in enumerate(rendered.frames):
        inputs = FrameInputs(seq=k, t=t, wall=WALL + t, joints=joints)
        model = pipeline.step(image, inputs).world
        assert model is not None
        out.append(model)
    return out


def test_percept_track_keeps_the_people_out_of_its_tracks(rendered: Rendered) -> None:
    """``percept track``'s frames (:func:`track_frames` with :class:`Agents`) judge the people
    as the daemon does: their anchors' rows go to the agents, none of the tracks' rows lies on
    a person, and the three objects are tracked."""
    profile = load_profile(PROFILE)
    settings = experiment("a")
    height, width = rendered.empty[0].shape[:2]
    camera = CameraModel.from_lens(profile.camera.lens, width, height)
    tree = KinematicTree.from_settings(profile.kinematics)
    poses: list[CameraPose | None] = [tree.camera_pose(j) for _, _, j, _ in rendered.frames]
    perception = Perception(settings.perception, width, height, camera)
    perception.calibrate(rendered.empty)  # (as the daemon's pipeline: the head still)
    agents = Agents(settings.features, width, height, camera)
    frames = ((t, image) for t, image, _, _ in rendered.frames)
    tracks = track_frames(perception, frames, poses, None, agents)
    assert tracks.agent_rows and agents.ids
    objects: set[int] = set()
    for row in tracks.rows:
        index, number, *box = (float(v) for v in row.split(",")[:6])
        people = rendered.frames[int(index) - 1][3]
        assert not people or covered(np.array([box]), np.array(people)).max() < 0.3, row
        objects.add(int(number))
    assert len(objects) == 3


@pytest.mark.timeout(120)
def test_a_person_beside_the_table_is_an_agent_never_an_object(worlds: list[World]) -> None:
    standing = [w for w in worlds if 3.0 <= w.t <= 20.5]  # type: ignore[operator]
    with_agent = [w for w in standing if any(a.visible for a in w.agents)]
    assert len(with_agent) >= 0.9 * len(standing)
    agent = next(a for w in with_agent for a in w.agents)
    assert agent.reason == "entered_moving"
    # In the robot's ground frame the person stands about 1.07 m ahead, 0.4 m to the right.
    assert agent.x == pytest.approx(STANDS[0] - ROBOT_X, abs=0.25)
    assert agent.y == pytest.approx(STANDS[1], abs=0.25)
    for w in worlds:
        assert w.t is not None
        assert len(w.objects) <= 3, (w.t, w.objects)  # the three objects, never the people
        for o in w.objects:
            assert o.position is not None and o.position[0] < 0.95, (w.t, o)
        if w.t > 1.0:
            assert len(w.objects) == 3
    # The world model with its agents passes its own check, and reads back the same.
    message = json.loads(encode(with_agent[-1]))
    assert message["agents"][0]["reason"] == "entered_moving"
    assert decode(json.dumps(message).encode(), World.SCHEMA) == with_agent[-1]


def test_an_agent_with_an_unknown_reason_is_refused(worlds: list[World]) -> None:
    message = json.loads(encode(next(w for w in worlds if w.agents)))
    message["agents"][0]["reason"] = "ghost"
    with pytest.raises(MessageError, match="reason"):
        decode(json.dumps(message).encode(), World.SCHEMA)
    del message["agents"]  # optional: a world model without agents has none
    assert decode(json.dumps(message).encode(), World.SCHEMA).agents == ()  # type: ignore[union-attr]


W, H = 320, 200


def _anchor(
    anchor: str, bbox: tuple[float, float, float, float], t: float, now: float | None = None
) -> Anchor:
    """An anchor born at ``t`` with ``bbox``, as it stands at ``now`` (default: at its birth)."""
    now = t if now is None else now
    return snapshot(
        {"id": anchor, "bbox": bbox, "histograms": np.ones((3, 8)) / 8, "created": t,
         "last_seen": now, "stamp": now, "in_motion": False, "velocity": (0.0, 0.0),
         "pixels": 50, "whole": True, "remembered": False}
    )  # fmt: skip


def _percepts(*boxes: tuple[float, float, float, float]) -> PerceptSet:
    k = len(boxes)
    return PerceptSet(
        np.array(boxes, float).reshape(k, 4), np.ones((k, 3, 8)) / 8, np.full(k, 50), np.arange(k)
    )


CORNER = (250.0, 0.0, 70.0, 90.0)
"""A figure-sized block at the right-hand top corner."""


def _motion(moved: tuple[float, float, float, float] | None) -> Motion:
    """The motion between two frames: a block came in at ``moved`` (left, top, width,
    height), or nothing changed (None)."""
    previous = np.full((H, W, 3), 128, np.uint8)
    current = previous.copy()
    if moved is not None:
        left, top, width, height = (int(v) for v in moved)
        current[top : top + height, left : left + width] = (60, 140, 110)
    upper = np.full((H, W, 3), 12, np.uint8)
    return Motion(current, previous, (np.zeros_like(upper), upper), None)


def test_tall_regions_are_agents_while_tall() -> None:
    judge = AgentJudge(0.6, W, H)
    anchor = _anchor("o1", (100.0, 60.0, 30.0, 80.0), 1.0)
    assert judge.reason(anchor, 0.12) is None
    assert judge.reason(anchor, 1.6) == "tall"
    assert judge.reason(anchor, None) is None
    assert judge.reason(anchor, 0.59) is None


TURN = np.array([[1.0, 0.0, -4.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
"""A turn of the head to the right: the view's content moves 4 pixels left."""
TURN_DOWN = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 5.0], [0.0, 0.0, 1.0]])
"""A tilt of the head up: the view's content moves 5 pixels down, in through the top border."""


def _walk_in(
    judge: AgentJudge,
    start: float,
    frames: int,
    turned: bool = False,
    where: tuple[float, float, float, float] = CORNER,
) -> None:
    """Moving foreground at ``where`` (at the border) in ``frames`` frames a tenth apart."""
    for k in range(frames):
        judge.watch(_percepts(where), _motion(where), start + k / 10, TURN if turned else None)


def test_what_came_in_moving_through_the_border_is_an_agent_for_good() -> None:
    judge = AgentJudge(0.6, W, H)
    _walk_in(judge, 1.0, 5)
    person = _anchor("o5", (230.0, 0.0, 90.0, 88.0), 2.0)
    assert judge.reason(person, 0.26) == "entered_moving"
    # Born clear of the border where the motion was (an object put down by a hand): an object.
    put = _anchor("o6", (240.0, 20.0, 20.0, 20.0), 2.0)
    assert judge.reason(put, 0.05) is None
    judge.next_frame(["o5", "o6"])
    assert judge.reason(person, 0.2) == "entered_moving"
    # How it came in alone (no height, as without a camera pose: standing in view and
    # reaching out of its top, it would be taller than the view shows):
    # an object that appears at the border changes one frame: it is an object.
    appeared = AgentJudge(0.6, W, H)
    _walk_in(appeared, 1.0, 1)
    assert appeared.reason(person, None) is None
    # Moving foreground seen while the head turned, or more than 3 s before: no one came in.
    turned = AgentJudge(0.6, W, H)
    _walk_in(turned, 1.0, 5, turned=True)
    assert turned.reason(person, None) is None
    late = AgentJudge(0.6, W, H)
    _walk_in(late, 1.0, 5)
    late.watch(_percepts(), _motion(None), 4.5, None)
    later = _anchor("o7", (230.0, 0.0, 90.0, 88.0), 4.5)
    assert late.reason(later, None) is None


def test_what_grows_from_the_border_while_young_came_in_moving() -> None:
    """Legs walking towards the camera: little of them moves from frame to frame, but their
    box grows from the top border into the view; a still object cut by the border keeps its
    box, objects put down beside one another at a border grow their anchor along it, and a turn
    that brings the scene in through that border may grow a box without a walk. How they came in
    alone: no height, as without a camera pose (with one, the legs standing in view and
    reaching out of its top would be taller than the view shows from the start)."""
    grown, still, turned, joined = (AgentJudge(0.6, W, H) for _ in range(4))
    legs = [(136.0, 0.0, 43.0, 25.0 + 5 * k) for k in range(6)]
    # At the bottom border, objects put down beside one another: their anchor grows along it.
    beside = [(121.0, 122.0, 58.0 + 10 * k, 78.0) for k in range(6)]
    for k, box in enumerate(legs):
        t = 2.0 + k / 10
        for judge in (grown, still, turned, joined):
            turn = TURN_DOWN if judge is turned else None
            judge.watch(_percepts(), _motion(None), t, turn)
        assert still.reason(_anchor("o1", legs[0], 2.0, t), None) is None
        verdict = grown.reason(_anchor("o1", box, 2.0, t), None)
        # (the box at birth covers 25 of its 40 rows at k = 3, 0.62; of 45 at k = 4, 0.56)
        assert verdict == ("entered_moving" if k >= 4 else None)
        assert turned.reason(_anchor("o1", box, 2.0, t), None) is None
        assert joined.reason(_anchor("o1", beside[k], 2.0, t), 0.2) is None
    # Older than the entry's seconds, a box that grows is no longer a sign of coming in.
    late = AgentJudge(0.6, W, H)
    assert late.reason(_anchor("o2", legs[0], 2.0, 2.0), None) is None
    assert late.reason(_anchor("o2", legs[-1], 2.0, 6.0), None) is None


def test_what_came_in_moving_is_judged_by_its_height_once_wholly_in_view() -> None:
    """An arm reached in from the top border and left an object where it reached: the anchor
    born of both came in moving, but once its box is clear of the border it is the object."""
    judge = AgentJudge(0.6, W, H)
    _walk_in(judge, 1.0, 5)
    assert judge.reason(_anchor("o1", (230.0, 0.0, 90.0, 88.0), 2.0), 0.3) == "entered_moving"
    left = _anchor("o1", (262.0, 70.0, 20.0, 26.0), 2.0, 3.0)
    assert judge.reason(left, 0.08) is None
    assert judge.reason(left, 1.6) == "tall"  # (seen whole, a person is told by their height)


BOTTOM = (140.0, 110.0, 60.0, 90.0)
"""An arm reaching in through the bottom border, before the robot."""


def test_what_an_arm_put_down_at_the_bottom_border_is_an_object() -> None:
    """An arm reached in through the bottom border and put an object down where the border
    cuts it: the anchor came in moving, but cut by the bottom border alone it is the object
    (what the bottom border cuts lies close before the robot; a person there reaches out of
    the top of the view too), where one cut by the top or a side border stays an agent."""
    judge = AgentJudge(0.6, W, H)
    _walk_in(judge, 1.0, 5, where=BOTTOM)
    put = _anchor("o1", (150.0, 150.0, 40.0, 50.0), 1.6)
    assert judge.reason(put, 0.01) is None
    judge.next_frame(["o1"])
    assert judge.reason(_anchor("o1", (150.0, 150.0, 40.0, 50.0), 1.6, 5.0), 0.01) is None
    # Reaching in through the bottom and out of the top (an arm, a person close by): an agent.
    arm = AgentJudge(0.6, W, H)
    _walk_in(arm, 1.0, 5, where=(140.0, 0.0, 60.0, 200.0))
    assert arm.reason(_anchor("o2", (145.0, 0.0, 50.0, 200.0), 1.6), 0.4) == "entered_moving"
    # Cut by a side border, what came in moving stays an agent (here without a height).
    side = AgentJudge(0.6, W, H)
    _walk_in(side, 1.0, 5, where=(270.0, 60.0, 50.0, 90.0))
    assert side.reason(_anchor("o3", (275.0, 70.0, 45.0, 80.0), 1.6), None) == "entered_moving"


def test_what_stands_in_view_and_reaches_out_of_its_top_is_an_agent() -> None:
    """A person standing still whom a turn of the head brought into view, cut by the top
    border with their feet in view: no one came in, and the height in view (what the top
    border's ray proves) is well under ``max_object_height``, yet they are taller than the view
    shows: an agent while the top border cuts them, also when remembered out of view; seen to
    their top, their height tells. Cut at the bottom too, or without a height, it is not known
    to stand in view."""
    judge = AgentJudge(0.6, W, H)
    judge.watch(_percepts((136.0, 0.0, 78.0, 56.0)), _motion(None), 18.7, TURN)
    person = _anchor("o6", (136.0, 0.0, 78.0, 56.0), 18.7)
    assert judge.reason(person, 0.19) == "tall"
    judge.next_frame(["o6"])
    judge.watch(_percepts(), _motion(None), 19.0, None)
    gone = replace(_anchor("o6", (-90.0, 0.0, 78.0, 56.0), 18.7, 19.0), remembered=True)
    assert judge.reason(gone, 0.19) == "tall"
    whole = _anchor("o6", (136.0, 30.0, 30.0, 40.0), 18.7, 19.5)
    assert judge.reason(whole, 0.12) is None
    assert judge.reason(whole, 1.7) == "tall"
    assert judge.reason(_anchor("o7", (136.0, 0.0, 78.0, 56.0), 20.0), None) is None
    assert judge.reason(_anchor("o8", (136.0, 0.0, 78.0, 200.0), 20.0), 0.3) is None
