"""Moving heads (issue 16, items 5 and 6): the shipped scenes with moving heads, the daemon's
calibration over the head's sweep with each frame's camera pose, and ``percept track --robot``
on a ``percept sim`` sequence whose head moves."""

from __future__ import annotations

import itertools
import math
import time
from pathlib import Path

import numpy as np
import pytest

from percept.runtime.daemon.devices import head_sweep
from percept.runtime.settings.scene import find_scene, load_scene
from tests.support.daemon import experiment_copy

ROOT = Path(__file__).resolve().parents[2]
OP3 = ROOT / "config" / "robots" / "robotis-op3.toml"

# tabletop-basic whose robot a pans its head from -0.6 to +0.6 rad while the floor is empty
# (the first object comes at 2 s), then holds it at +0.6.
SWEEP = (
    "joints.head_tilt = { offset = -0.5 }\n",
    "joints.head_tilt = { offset = -0.5 }\n"
    "joints.head_pan = { keyframes = [[0.0, -0.6], [2.0, 0.6]] }\n",
)


def scene_copy(tmp: Path, *edits: tuple[str, str], count: int = 1) -> Path:
    """tabletop-basic with ``edits`` (the first ``count`` occurrences of each), beside it."""
    text = find_scene("tabletop-basic").read_text()
    for old, new in edits:
        assert old in text
        text = text.replace(old, new, count)
    text = text.replace('"../', f'"{ROOT / "config"}/')
    path = tmp / "scene.toml"
    path.write_text(text)
    return path


def heading(R: np.ndarray) -> float:
    """The azimuth of a camera's optical axis (its x axis) in the robot's ground frame."""
    return math.atan2(R[1, 0], R[0, 0])


# -- the shipped scenes ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["tabletop-look", "tabletop-pan"])
def test_shipped_moving_head_scenes_sweep_over_the_empty_floor_then_look_around(name):
    scene, platforms = load_scene(find_scene(name))
    assert set(platforms) == {"a", "b"}
    for robot in scene.robots:
        sweep = head_sweep(scene, robot.name)
        assert 6.0 <= sweep <= 8.0  # the empty floor while the head sweeps
        low, high = robot.joints["head_pan"].bounds()
        assert low <= -0.9 and high >= 0.9  # the working range the objects are seen in
        # after the sweep the head still turns: by at least 0.5 rad
        later = [robot.joints["head_pan"].angle(t) for t in np.arange(sweep, scene.duration, 0.1)]
        assert max(later) - min(later) >= 0.5
    assert not any(o.present for o in scene.objects)
    assert {"add", "remove", "move"} <= {e.action for e in scene.timeline}


def test_look_scene_changes_objects_out_of_robot_as_view(tmp_path):
    """What tabletop-look promises: the objects moved, removed or added while robot a looks
    away are out of its view then, and in view when it looks ahead again."""
    from percept.runtime.settings.scene import open_world

    scene, _ = load_scene(find_scene("tabletop-look"))
    changed = [e for e in scene.timeline if e.t > 11.0]
    with open_world("tabletop-look") as world:
        for e in changed:
            # just before it goes, or once it has come or moved
            t = e.t - 0.05 if e.action == "remove" else e.t + e.span + 0.05
            during = world.truth(t, views=["a"]).views["a"].objects[e.object]
            assert during.pixels == 0, f"object {e.object} at t={t} is in a's view"
        ahead = world.truth(31.0, views=["a"]).views["a"].objects
        for e in changed:
            seen = e.object in ahead and ahead[e.object].pixels > 0
            assert seen == (e.action != "remove")


def test_still_heads_have_no_sweep():
    for name in ("tabletop-basic", "tabletop-busy"):
        scene, _ = load_scene(find_scene(name))
        assert all(head_sweep(scene, r.name) == 0.0 for r in scene.robots)


# -- the daemon's calibration -------------------------------------------------------------------


def _calibrate(tmp_path: Path, scene: Path) -> tuple[list, list[float], float]:
    """The daemon's calibration of robot a on ``scene`` (joints read directly): the camera
    poses the perception's calibration got, the scene times of its frames, and the sweep."""
    from percept.runtime.daemon.daemon import Daemon
    from percept.runtime.daemon.devices import open_devices
    from percept.runtime.daemon.pipeline import Pipeline
    from percept.runtime.daemon.settings import DaemonOptions
    from percept.runtime.record.telemetry import Telemetry

    experiment = experiment_copy(tmp_path, ('joints = "emulator"', 'joints = "direct"'))
    daemon = Daemon(DaemonOptions("a", OP3, experiment, sim_scene=str(scene)))
    devices = open_devices("a", daemon.profile, daemon.experiment, sim_scene=str(scene))
    pipeline = Pipeline("a", daemon.profile, daemon.experiment, 320, 200, joint_max_age=0.05)
    perception = pipeline.perception
    calibrate = perception.calibrate
    got: dict[str, list] = {"poses": [], "times": [], "images": []}

    def watched(frames, progress=None, poses=None):
        # the real calibration on the daemon's frames and poses, noted on the way (the stream
        # is endless: the calibration takes the first calibration_frames)
        assert poses is not None
        needed = perception.params.background.calibration_frames
        for image, pose in itertools.islice(zip(frames, poses, strict=False), needed):
            got["times"].append(devices.clock.at(time.monotonic()))
            got["poses"].append(pose)
            got["images"].append(image)
        return calibrate(got["images"], progress, got["poses"])

    perception.calibrate = watched  # an instance spy: the daemon's own calibration runs
    devices.start()
    try:
        assert daemon._prepare_background(pipeline, devices, Telemetry())
    finally:
        devices.close()
    assert perception.background is not None
    return got["poses"], got["times"], devices.sweep


def test_daemon_calibration_lets_scene_time_run_over_the_sweep_with_each_frames_pose(tmp_path):
    scene = scene_copy(tmp_path, SWEEP)
    poses, times, sweep = _calibrate(tmp_path, scene)
    assert sweep == 2.0
    assert len(poses) == 30  # calibration_frames, each with its pose
    headings = [heading(p.R) for p in poses]
    # the head swept from -0.6 to +0.6 rad during the calibration: the poses follow it
    assert headings[0] < -0.35 and headings[-1] > 0.35
    assert all(b >= a - 1e-9 for a, b in itertools.pairwise(headings))
    assert max(times) < sweep + 0.1  # all on the empty floor (times read just after)


def test_daemon_calibration_holds_a_still_scene_at_time_zero(tmp_path):
    poses, times, sweep = _calibrate(tmp_path, scene_copy(tmp_path))
    assert sweep == 0.0
    assert len(poses) == 30
    assert times == [0.0] * 30
    assert all(np.allclose(p.R, poses[0].R) for p in poses)
