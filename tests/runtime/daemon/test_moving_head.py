"""Moving heads (issue 16, items 5 and 6): the shipped scenes with moving heads, the daemon's
calibration over the head's sweep with each frame's camera pose, and ``percept track --robot``
on a ``percept sim`` sequence whose head moves."""

from __future__ import annotations

import itertools
import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

from percept.runtime.daemon.devices import head_sweep
from percept.runtime.settings.scene import find_scene, load_scene
from tests.support.daemon import experiment_copy

ROOT = Path(__file__).resolve().parents[3]
OP3 = ROOT / "config" / "robots" / "robotis-op3.toml"

# tabletop-basic whose robot a looks right (-0.6 rad) for 0.8 s, then pans to +0.6 rad while the
# floor is empty (the first object comes at 2 s), then holds it there.
SWEEP = (
    "joints.head_tilt = { offset = -0.5 }\n",
    "joints.head_tilt = { offset = -0.5 }\n"
    "joints.head_pan = { keyframes = [[0.0, -0.6], [0.8, -0.6], [2.0, 0.6]] }\n",
)


def scene_copy(tmp: Path, *edits: tuple[str, str], count: int = 1) -> Path:
    """tabletop-basic with ``edits`` (the first ``count`` occurrences of each), beside it."""
    text = find_scene("tabletop-basic").read_text(encoding="utf-8")
    for old, new in edits:
        assert old in text
        text = text.replace(old, new, count)
    text = text.replace('"../', f'"{ROOT / "config"}/')
    path = tmp / "scene.toml"
    path.write_text(text, encoding="utf-8")
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


def _calibrate(tmp_path: Path, scene: Path, gaze: bool = False) -> tuple[list, list[float], float]:
    """The daemon's calibration of robot a on ``scene`` (joints read directly, or with
    ``gaze`` through the servo emulator with gaze on): the camera poses the perception's
    calibration got, the scene times of its frames, and the devices' sweep."""
    from percept.runtime.daemon.daemon import Daemon
    from percept.runtime.daemon.devices import open_devices
    from percept.runtime.daemon.pipeline import Pipeline
    from percept.runtime.daemon.settings import DaemonOptions
    from percept.runtime.record.telemetry import Telemetry

    if gaze:
        edits = [("enabled = false", "enabled = true"), ("max_speed = 1.0", "max_speed = 4.0")]
    else:
        edits = [('joints = "emulator"', 'joints = "direct"')]
    experiment = experiment_copy(tmp_path, *edits)
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
        daemon.gaze = daemon._open_gaze(devices)
        assert (daemon.gaze is not None) == gaze
        assert daemon.perceiving.background.prepare(pipeline, devices, Telemetry(), daemon.gaze)
        if gaze:  # the sweep ends where the head was (where the scene starts it: -0.6)
            sample = devices.joints.latest()
            assert sample is not None and abs(sample.angles["head_pan"] + 0.6) < 0.01
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
    assert times[-1] >= 0.9 * sweep  # the scene's time ran through the sweep


def test_daemon_calibration_holds_a_still_scene_at_time_zero(tmp_path):
    poses, times, sweep = _calibrate(tmp_path, scene_copy(tmp_path))
    assert sweep == 0.0
    assert len(poses) == 30
    assert times == [0.0] * 30
    assert all(np.allclose(p.R, poses[0].R) for p in poses)


# -- percept track --robot ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def panning_sequence(tmp_path_factory):
    """``percept sim`` of robot a on tabletop-basic with its head sweeping while the floor is
    empty (2 s) and turning again while the objects are there."""
    from percept.runtime.cli import main

    tmp = tmp_path_factory.mktemp("panning")
    scene = scene_copy(
        tmp,
        (
            SWEEP[0],
            SWEEP[0] + "joints.head_pan = { keyframes = [[0.0, -0.6], [2.0, 0.6], [4.5, 0.0]] }\n",
        ),
    )
    out = tmp / "seq"
    assert (
        main(["sim", "--scene", str(scene), "--robot", "a", "--out", str(out), "--seconds", "5"])
        == 0
    )
    return out


def test_sim_records_the_joints_of_a_moving_head(panning_sequence):
    import csv

    with (panning_sequence / "joints.csv").open(encoding="utf-8") as f:
        pans = [float(r["head_pan"]) for r in csv.DictReader(f)]
    assert len(pans) == 150
    assert min(pans) == pytest.approx(-0.6) and max(pans) == pytest.approx(0.6, abs=0.01)


def test_track_with_robot_takes_each_frames_pose_from_the_recorded_joints(panning_sequence):
    from percept.runtime.commands import _sequence
    from percept.runtime.commands.offline.track import MovingCamera

    sequence = _sequence.open_sequence(panning_sequence)
    moving = MovingCamera("robotis-op3", sequence)
    truth = [json.loads(line) for line in (panning_sequence / "truth.jsonl").open(encoding="utf-8")]
    assert len(moving.poses) == len(truth) == 150
    for pose, record in zip(moving.poses, truth, strict=True):
        # the camera pose forward kinematics gives is the one the world rendered from
        assert pose is not None
        np.testing.assert_allclose(pose.R, record["camera"]["R"], atol=1e-4)
        np.testing.assert_allclose(pose.t, record["camera"]["t"], atol=1e-4)
    assert moving.camera.width == 320 and moving.camera.height == 200


def test_track_with_robot_writes_the_visible_anchors_of_a_panning_sequence(
    panning_sequence, tmp_path, capsys
):
    from percept.runtime.cli import main

    tracks = tmp_path / "tracks.txt"
    args = ["track", str(panning_sequence), "--out", str(tracks), "--robot", "robotis-op3"]
    assert main([*args, "--calibration-frames", "60"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["frames"] == 150 and summary["camera_poses"] == 150
    assert summary["anchors_created"] >= 1 and summary["marker_boxes"] == 2
    rows = [line.split(",") for line in tracks.read_text(encoding="utf-8").splitlines()]
    assert rows and all(1 <= int(r[0]) <= 150 for r in rows)
    # without --robot: the profile the percept sim folder names, the same poses
    assert main(["track", str(panning_sequence), "--out", str(tmp_path / "named.txt")]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["camera_poses"] == 150


def test_track_places_the_marker_boxes_as_known_objects(panning_sequence):
    """``percept track`` places the marker boxes with the daemon's search and box fit: the
    corners it passes to perception as known objects are those of the boxes the simulator
    drew, in the robot's ground frame; ``--no-markers`` passes none."""
    import argparse

    from percept.perception.tracking.known import box_corners
    from percept.runtime.commands import _sequence
    from percept.runtime.commands.offline import track

    parser = argparse.ArgumentParser()
    track.add_arguments(parser)
    sequence = _sequence.open_sequence(panning_sequence)
    moving = track.MovingCamera("robotis-op3", sequence)
    args = parser.parse_args([str(panning_sequence), "--out", "unused.txt"])
    boxes = track.known_marker_boxes(args, sequence, moving, 1)
    assert boxes is not None
    known = []
    for k, pose in enumerate(moving.poses):
        assert pose is not None
        known = boxes.known(k, k / sequence.fps, pose)
    assert boxes.placed == {1, 2} and len(known) == 2
    truth = json.loads(next(iter((panning_sequence / "truth.jsonl").open(encoding="utf-8"))))
    for drawn in truth["boxes"]:
        x, y, theta = drawn["ground"]
        corners = box_corners(x, y, theta, (0.18, 0.18, 0.18))
        # some placed box has every corner of the drawn one within 2 cm
        assert (
            min(
                np.linalg.norm(corners[:, None] - found[None], axis=2).min(axis=1).max()
                for found in known
            )
            < 0.02
        )
    off = parser.parse_args([str(panning_sequence), "--out", "unused.txt", "--no-markers"])
    assert track.known_marker_boxes(off, sequence, moving, 1) is None


def test_track_searches_markers_in_the_grey_image_the_daemon_searches(tmp_path):
    import cv2

    from percept.runtime.commands import _sequence

    rng = np.random.default_rng(3)
    image = cv2.GaussianBlur(rng.integers(0, 256, (48, 64, 3), dtype=np.uint8), (5, 5), 0)
    assert cv2.imwrite(str(tmp_path / "000001.jpg"), image)
    assert cv2.imwrite(str(tmp_path / "000002.png"), image)
    sequence = _sequence.open_sequence(tmp_path)
    jpeg = str(tmp_path / "000001.jpg")
    # at a grid the daemon's camera decodes a JPEG's luma for the search; at full size its BGR
    luma, bgr = cv2.imread(jpeg, cv2.IMREAD_GRAYSCALE), cv2.imread(jpeg)
    assert np.array_equal(sequence.search_image(0, 2), luma)
    assert np.array_equal(sequence.search_image(0, 1), cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
    assert np.array_equal(sequence.search_image(1, 2), cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))


def test_track_with_robot_refuses_a_sequence_without_joint_angles(tmp_path, capsys):
    import cv2

    from percept.runtime.cli import main

    (tmp_path / "img1").mkdir()
    for k in range(1, 4):
        cv2.imwrite(str(tmp_path / "img1" / f"{k:06d}.png"), np.zeros((200, 320, 3), np.uint8))
    out = tmp_path / "tracks.txt"
    assert main(["track", str(tmp_path), "--out", str(out), "--robot", "robotis-op3"]) == 2
    assert "no recorded joint angles" in capsys.readouterr().err


def test_track_with_robot_reads_the_joints_of_an_mcap_recording(panning_sequence, tmp_path, capsys):
    """The daemon records each frame's joint angles with its image: the same poses come out."""
    import csv

    import cv2

    from percept.runtime.cli import main
    from percept.runtime.commands import _sequence
    from percept.runtime.commands.offline.track import MovingCamera
    from percept.runtime.record.telemetry import Telemetry

    with (panning_sequence / "joints.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))[:90]
    telemetry = Telemetry(raw_images=True)
    recording = tmp_path / "a.mcap"
    telemetry.record(recording, metadata={"robot": "a"})
    for row in rows:
        k = int(row["frame"])
        image = cv2.imread(str(panning_sequence / "img1" / f"{k:06d}.png"))
        joints = {"head_pan": float(row["head_pan"]), "head_tilt": float(row["head_tilt"])}
        inputs = {"seq": k, "t": float(row["t"]), "wall": 1.8e9 + k / 30, "joints": joints}
        telemetry.log_frame(inputs, image)
    telemetry.close()

    moving = MovingCamera("robotis-op3", _sequence.open_sequence(recording))
    truth = [
        json.loads(line) for line in (panning_sequence / "truth.jsonl").open(encoding="utf-8")
    ][:90]
    for pose, record in zip(moving.poses, truth, strict=True):
        assert pose is not None
        np.testing.assert_allclose(pose.R, record["camera"]["R"], atol=1e-4)
    out = tmp_path / "tracks.txt"
    assert main(["track", str(recording), "--out", str(out), "--robot", "robotis-op3"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["frames"] == 90 and summary["camera_poses"] == 90


def test_daemon_calibration_with_gaze_sweeps_the_pan_range_through_the_servos(tmp_path):
    """Gaze on: the head follows the servos, the scene holds at time 0 (the empty floor) and
    the calibration sweep is the gaze's, over the pan joint's whole range (+-1.57 rad)."""
    poses, times, sweep = _calibrate(tmp_path, scene_copy(tmp_path, SWEEP), gaze=True)
    assert sweep == 0.0  # the scene's keyframes are not played: the servos move the head
    assert times == [0.0] * 30
    headings = [heading(p.R) for p in poses]
    assert min(headings) < -1.2 and max(headings) > 1.2
