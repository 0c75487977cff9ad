"""The simulated world against its own ground truth and against the kinematics: renders of real
MuJoCo scenes, checked pixel by pixel with OpenCV."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from percept.config.loader import ConfigError, build
from percept.drivers.sim.model import BOX_LABEL
from percept.drivers.sim.scene import Scene, SceneError
from percept.drivers.sim.world import SimWorld
from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import invert, marker_on_box
from percept.kinematics.tree import KinematicTree
from percept.runtime.settings.experiment import load_experiment
from percept.runtime.settings.profile import load_profile
from percept.runtime.settings.scene import find_scene, load_scene

pytestmark = pytest.mark.timeout(120)

ROOT = Path(__file__).resolve().parents[3]
ROBOTS = ROOT / "config" / "robots"


def open_scene(name: str) -> SimWorld:
    scene, platforms = load_scene(find_scene(name))
    return SimWorld(scene, platforms)


@pytest.fixture(scope="module")
def basic() -> SimWorld:
    with open_scene("tabletop-basic") as world:
        yield world


@pytest.fixture(scope="module")
def busy() -> SimWorld:
    with open_scene("tabletop-busy") as world:
        yield world


def scene_from(data: dict[str, Any]) -> Scene:
    return build(Scene, data, ROOT / "config" / "scenes" / "test.toml")


def one_robot(profile: str, **robot: Any) -> dict[str, Any]:
    return {
        "name": "test",
        "robots": [{"name": "a", "profile": str(ROBOTS / f"{profile}.toml"), **robot}],
    }


def _pose(p) -> np.ndarray:
    """4x4 world <- ground pose (x, y, yaw)."""
    T = np.eye(4)
    T[:2, :2] = [[math.cos(p[2]), -math.sin(p[2])], [math.sin(p[2]), math.cos(p[2])]]
    T[:2, 3] = p[:2]
    return T


def chroma(rgb: np.ndarray) -> np.ndarray:
    """Colour without brightness: r, g over r + g + b (lighting scales all three alike)."""
    rgb = np.asarray(rgb, dtype=float)
    return rgb[..., :2] / np.maximum(rgb.sum(axis=-1, keepdims=True), 1.0)


# -- the shipped scenes -----------------------------------------------------------------------


@pytest.mark.parametrize("name", ["tabletop-basic", "tabletop-busy"])
def test_shipped_scene_has_two_robots_looking_at_a_shared_area_from_different_sides(name):
    with open_scene(name) as world:
        truth = world.truth(5.0, views=[])
        axes = []
        for robot in truth.robots.values():
            forward = robot.camera_world.R[:, 0]
            axes.append(math.atan2(forward[1], forward[0]))
            # the camera looks down at the floor near the middle of the scene
            t = robot.camera_world.t
            hit = t + forward * (-t[2] / forward[2])
            assert np.linalg.norm(hit[:2]) < 0.25
        apart = abs(math.degrees(math.remainder(axes[0] - axes[1], 2 * math.pi)))
        assert 90 <= apart <= 150
        # every object (when there) is in both robots' images
        full = world.truth(29.0 if name == "tabletop-busy" else 9.0)
        for view in full.views.values():
            assert all(v.pixels > 0 for v in view.objects.values())


def test_basic_scene_holds_still_objects_and_busy_scene_everything_the_experimenter_does():
    basic, _ = load_scene(find_scene("tabletop-basic"))
    busy, _ = load_scene(find_scene("tabletop-busy"))
    assert 4 <= len(basic.objects) <= 6 and len(basic.boxes) == 2
    assert {e.action for e in basic.timeline} == {"add"}
    assert len(busy.objects) >= 8
    assert {e.action for e in busy.timeline} == {"add", "remove", "move", "lay_down", "in_front"}
    for scene in (basic, busy):
        shapes = {o.shape for o in scene.objects}
        assert {"block", "cuboid", "cylinder", "cone", "toy"} <= shapes
        # the floor is empty at first, for the background calibration
        assert not any(o.present for o in scene.objects)
        assert min(e.t for e in scene.timeline) >= 2.0


def test_scene_boxes_are_the_experiments_landmark_boxes():
    from percept.perception.landmarks.geometry import marker_in_box

    landmarks = {
        b.id: b for b in load_experiment(ROOT / "config/experiments/tabletop.toml").landmarks.boxes
    }
    for name in ("tabletop-basic", "tabletop-busy"):
        scene, _ = load_scene(find_scene(name))
        assert {b.id for b in scene.boxes} == set(landmarks)
        for box in scene.boxes:
            expected = landmarks[box.id]
            assert box.size == expected.size
            ours = {m.id: m for m in box.markers}
            assert set(ours) == {m.id for m in expected.markers}
            for m in expected.markers:
                np.testing.assert_allclose(
                    marker_on_box(box.size, ours[m.id].face, ours[m.id].offset, ours[m.id].roll),
                    marker_in_box(expected, m),
                    atol=1e-12,
                )


# -- the rendering agrees with the kinematics and the camera model ------------------------------


@pytest.mark.parametrize("profile", ["robotis-op3", "sony-humanoid", "myon"])
def test_a_known_point_renders_where_the_camera_model_projects_it(profile):
    """Small balls on the floor: the centre of each ball's pixels is within 1 px of where
    forward kinematics (kinematics.tree, not MuJoCo) and CameraModel.project put its centre."""
    pose = (0.3, -0.2, 0.6)
    motion = {
        "head_pan": {"offset": 0.05, "amplitude": 0.2, "period": 3.0},
        "head_tilt": {"offset": -0.55, "amplitude": 0.1, "period": 5.0, "phase": 1.0},
    }
    data = one_robot(profile, pose=list(pose), joints=motion)
    platform = load_profile(ROBOTS / f"{profile}.toml")
    tree = KinematicTree.from_settings(platform.kinematics)
    lens = CameraModel.from_lens(
        platform.camera.lens, platform.camera.width, platform.camera.height
    )
    t = 1.3
    angles = {name: scene_from(data).robot("a").joints[name].angle(t) for name in motion}
    camera = tree.camera_pose(angles)
    world_from_camera = _pose(pose) @ camera.matrix()
    # a ball about 5 px wide where each of these pixels' rays meets the floor
    grid = [(u, v) for u in (0.25, 0.5, 0.75) for v in (0.55, 0.7, 0.85)]
    rays = lens.pixel_rays(np.array(grid) * (lens.width, lens.height))
    rays = rays @ world_from_camera[:3, :3].T
    origin = world_from_camera[:3, 3]
    balls = []
    for ray in rays:
        radius = 0.0
        for _ in range(3):  # the ball's size depends on its distance, which depends on its size
            reach = (radius - origin[2]) / ray[2]
            radius = 2.5 * reach * np.linalg.norm(ray) / lens.fx
        balls.append((origin + reach * ray, 2 * radius))
    data["objects"] = [
        {
            "id": i + 1,
            "shape": "ball",
            "size": [d, d, d],
            "color": [255, 0, 0],
            "pose": [float(p[0]), float(p[1]), 0.0],
        }
        for i, (p, d) in enumerate(balls)
    ]
    with SimWorld(scene_from(data), {"a": platform}) as world:
        truth = world.truth(t, views=[])
        np.testing.assert_allclose(truth.robots["a"].camera.R, camera.R, atol=1e-9)
        np.testing.assert_allclose(truth.robots["a"].camera.t, camera.t, atol=1e-9)
        labels = world.labels("a", t)
    to_camera = invert(world_from_camera)
    centres = np.array([p for p, _ in balls])
    expected = lens.project(centres @ to_camera[:3, :3].T + to_camera[:3, 3])
    for i, (u, v) in enumerate(expected):
        rows, cols = np.nonzero(labels == i + 1)
        assert rows.size > 5, f"ball {i + 1} hardly rendered"
        error = math.hypot(cols.mean() - u, rows.mean() - v)
        assert error < 1.0, (profile, i, error)


def test_rendered_markers_are_found_by_aruco_at_their_true_corners(basic):
    """cv2.aruco finds the printed markers with the right ids at the truth's projected corners:
    markers are upright, not mirrored, where the box says. Within 1 px for markers seen within
    50 degrees of head-on; texture filtering blurs more oblique ones a little."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(dictionary, params)
    frontal = 0
    for robot in basic.robots:
        image = basic.render(robot, 5.0, effects=False)
        corners, ids, _ = detector.detectMarkers(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))
        truth = basic.truth(5.0, [robot])
        camera = truth.robots[robot].camera_world.t
        assert ids is not None
        for c, marker_id in zip(corners, ids.ravel(), strict=True):
            seen = truth.views[robot].markers[int(marker_id)]
            assert seen.facing and seen.in_image
            error = np.max(np.linalg.norm(c.reshape(4, 2) - seen.corners, axis=1))
            box = next(b for b in basic.scene.boxes if b.id == seen.box)
            m = next(m for m in box.markers if m.id == marker_id)
            T = _pose(box.pose) @ marker_on_box(box.size, m.face, m.offset, m.roll)
            towards = (camera - T[:3, 3]) / np.linalg.norm(camera - T[:3, 3])
            if T[:3, 2] @ towards > math.cos(math.radians(50)):
                assert error < 1.0, (robot, marker_id, error)
                frontal += 1
            else:
                assert error < 2.0, (robot, marker_id, error)
    assert frontal >= 3


# -- the truth agrees with the rendering --------------------------------------------------------


def test_each_objects_true_box_holds_pixels_of_its_colour_and_fits_tightly(basic):
    for robot in basic.robots:
        image = cv2.cvtColor(basic.render(robot, 6.0, effects=False), cv2.COLOR_BGR2RGB)
        truth = basic.truth(6.0, [robot])
        assert len(truth.objects) == 5
        pixel_chroma = chroma(image)
        for obj in truth.objects.values():
            seen = truth.views[robot].objects[obj.id]
            assert seen.bbox is not None and seen.visible > 0.5
            left, top, w, h = seen.bbox
            like = np.linalg.norm(pixel_chroma - chroma(obj.color), axis=-1) < 0.06
            inside = like[top : top + h, left : left + w]
            assert inside.mean() > 0.3, (robot, obj.name, inside.mean())
            # and the box is tight: a rim of the box holds some, the 3 px around it hardly any
            grown = np.zeros_like(like)
            grown[max(top - 3, 0) : top + h + 3, max(left - 3, 0) : left + w + 3] = True
            grown[top : top + h, left : left + w] = False
            assert inside[0].any() and inside[-1].any() and inside[:, 0].any()
            assert like[grown].mean() < 0.1, (robot, obj.name)


def test_segmentation_labels_pixels_of_objects_and_boxes(basic):
    labels = basic.labels("a", 6.0)
    truth = basic.truth(6.0, ["a"])
    for obj_id, seen in truth.views["a"].objects.items():
        assert seen.pixels == int((labels == obj_id).sum())
    for box_id, (_, pixels) in truth.views["a"].boxes.items():
        assert pixels == int((labels == BOX_LABEL + box_id).sum()) and pixels > 0


def test_a_removed_object_is_gone_from_frames_and_truth(busy):
    cyan = next(o for o in busy.scene.objects if o.name == "cyan-block")
    removed = next(e.t for e in busy.scene.timeline if e.object == cyan.id and e.action == "remove")
    before, after = busy.truth(removed - 0.1), busy.truth(removed + 0.1)
    assert cyan.id in before.objects and cyan.id not in after.objects
    for robot in busy.robots:
        seen = before.views[robot].objects[cyan.id]
        assert seen.pixels > 50
        left, top, w, h = seen.bbox
        for t, expect in ((removed - 0.1, True), (removed + 0.1, False)):
            image = cv2.cvtColor(busy.render(robot, t, effects=False), cv2.COLOR_BGR2RGB)
            patch = chroma(image[top : top + h, left : left + w])
            like = np.linalg.norm(patch - chroma(cyan.color), axis=-1) < 0.06
            assert bool(like.mean() > 0.3) == expect
        assert cyan.id not in after.views[robot].objects
        assert not np.any(busy.labels(robot, removed + 0.1) == cyan.id)


def test_a_laid_down_block_changes_from_tall_to_wide(busy):
    event = next(e for e in busy.scene.timeline if e.action == "lay_down" and e.object == 1)
    before = busy.truth(event.t - 0.1, ["a"])
    during = busy.truth(event.t + event.span / 2, ["a"])
    after = busy.truth(event.t + event.span + 0.1, ["a"])
    _, _, w0, h0 = before.views["a"].objects[1].bbox
    _, _, w1, h1 = after.views["a"].objects[1].bbox
    assert h0 > 1.5 * w0 and w1 > 1.5 * h1
    assert before.objects[1].standing and not after.objects[1].standing
    assert not during.objects[1].standing
    size = before.objects[1].size
    assert before.objects[1].top == pytest.approx(size[2])
    assert after.objects[1].top == pytest.approx(size[0])
    # it fell onto the side face nearest the given heading: nothing sinks into the floor
    moved = after.objects[1].position - before.objects[1].position
    heading = math.atan2(moved[1], moved[0])
    sides = [before.objects[1].yaw + k * math.pi / 2 for k in range(4)]
    assert min(abs(math.remainder(heading - s, 2 * math.pi)) for s in sides) < 1e-9
    assert abs(math.remainder(heading - event.direction, 2 * math.pi)) <= math.pi / 4
    corners = busy.tracks[1].placement(event.t + event.span / 2).corners(busy.tracks[1].size)
    assert corners[:, 2].min() > -1e-9


def test_putting_one_object_in_front_of_another_hides_it_from_that_robot(busy):
    event = next(e for e in busy.scene.timeline if e.action == "in_front")
    before = busy.truth(event.t - 0.1, [event.robot]).views[event.robot].objects[event.target]
    after = busy.truth(event.t + event.span + 0.1, [event.robot]).views[event.robot]
    hidden = after.objects[event.target]
    assert before.visible == pytest.approx(1.0)
    assert hidden.visible < 0.9
    assert hidden.pixels < before.pixels
    # the unoccluded outline is the same as before: only the view of it changed
    assert hidden.bbox_full == before.bbox_full
    assert after.objects[event.object].visible == pytest.approx(1.0)


def test_truth_records_are_json_in_the_robots_own_frame(busy):
    record = busy.truth(12.0, ["b"]).record("b")
    text = json.dumps(record)
    assert json.loads(text)["robot"] == "b"
    me = np.array(record["pose"])
    for obj in record["objects"]:
        x, y = obj["position"][:2]
        c, s = math.cos(me[2]), math.sin(me[2])
        dx, dy = x - me[0], y - me[1]
        assert obj["ground"] == pytest.approx([c * dx + s * dy, -s * dx + c * dy], abs=1e-5)
    peer = next(r for r in record["robots"] if r["name"] == "a")
    a_pose = next(r.pose for r in busy.scene.robots if r.name == "a")
    T = invert(_pose(me)) @ _pose(a_pose)
    assert peer["ground"][:2] == pytest.approx(list(T[:2, 3]), abs=1e-5)
    # the camera pose in the record is where the optical axis meets the floor near objects
    R = np.array(record["camera"]["R"])
    assert R[2, 0] < -0.3  # looking down


# -- determinism --------------------------------------------------------------------------------


def test_same_scene_and_seed_give_identical_frames_and_truth_in_any_order(busy):
    times = [3.1, 12.3, 10.25, 19.9]
    first = {t: (busy.render("a", t), busy.truth(t).record("a")) for t in times}
    with open_scene("tabletop-busy") as again:
        for t in reversed(times):
            image, record = again.render("a", t), again.truth(t).record("a")
            assert np.array_equal(image, first[t][0])
            assert record == first[t][1]
    # the camera noise really is there, and depends on the seed
    assert not np.array_equal(busy.render("a", 3.1), busy.render("a", 3.1, effects=False))
    import dataclasses

    reseeded = dataclasses.replace(busy.scene, seed=busy.scene.seed + 1)
    with SimWorld(reseeded, {r: busy.robot_model(r).platform for r in busy.robots}) as other:
        assert not np.array_equal(other.render("a", 3.1), first[3.1][0])


# -- scene errors -------------------------------------------------------------------------------


def test_impossible_timelines_are_refused_with_the_event_named():
    base = one_robot("robotis-op3")
    base["objects"] = [
        {"id": 1, "shape": "block", "size": [0.04, 0.04, 0.1], "color": [200, 0, 0]},
        {"id": 2, "shape": "ball", "size": [0.05, 0.05, 0.05], "color": [0, 0, 200]},
    ]
    cases = [
        (
            [
                {"t": 1, "action": "remove", "object": 1},
                {"t": 2, "action": "move", "object": 1, "path": [[0.1, 0.1]]},
            ],
            "timeline[1] (move object 1 at t=2): the object is not there",
        ),
        (
            [
                {"t": 1, "action": "move", "object": 1, "path": [[0.1, 0.1]], "duration": 3},
                {"t": 2, "action": "remove", "object": 1},
            ],
            "still moving until t=4",
        ),
        (
            [
                {"t": 1, "action": "lay_down", "object": 1},
                {"t": 3, "action": "lay_down", "object": 1},
            ],
            "only a standing object can be laid down",
        ),
        ([{"t": 1, "action": "add", "object": 2}], "already there"),
        (
            [{"t": 1, "action": "in_front", "object": 1, "target": 2, "robot": "z"}],
            "no robot named",
        ),
        (
            [{"t": 1, "action": "remove", "object": 1, "path": [[0, 0]]}],
            "remove does not take path",
        ),
        ([{"t": 1, "action": "move", "object": 7, "path": [[0, 0]]}], "no object with id 7"),
    ]
    for events, message in cases:
        with pytest.raises(ConfigError, match=re.escape(message)):
            scene_from({**base, "timeline": events})
    with pytest.raises(ConfigError, match="a cylinder is round"):
        scene_from(
            {
                **base,
                "objects": [
                    {"id": 1, "shape": "cylinder", "size": [0.04, 0.05, 0.1], "color": [1, 2, 3]}
                ],
            }
        )


def test_a_joint_motion_beyond_the_servos_limits_is_refused():
    scene = scene_from(
        one_robot("robotis-op3", joints={"head_tilt": {"offset": -1.0, "amplitude": 0.3}})
    )
    platform = load_profile(ROBOTS / "robotis-op3.toml")
    with pytest.raises(SceneError) as err:
        SimWorld(scene, {"a": platform})
    assert err.value.key == "robots[0].joints.head_tilt"
    assert "beyond the joint's limits" in err.value.problem
    with pytest.raises(SceneError, match="no movable joint"):
        SimWorld(
            scene_from(one_robot("robotis-op3", joints={"neck": {"offset": 0.1}})), {"a": platform}
        )
