"""The simulated world behind the real interfaces: the camera as a FrameSource, the joints read
directly and through the Dynamixel emulator by the real DynamixelBus, and ``percept sim``'s
MOTChallenge output read by a standard tool (motmetrics)."""

from __future__ import annotations

import configparser
import json
import math
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.config.loader import build
from percept.drivers.dynamixel.bus import DynamixelBus
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.settings import GazeSettings
from percept.drivers.joints import JointSource
from percept.drivers.sim.camera import SimCamera
from percept.drivers.sim.clock import StepClock, WallClock
from percept.drivers.sim.joints import EmulatorBridge, SimJoints
from percept.drivers.sim.scene import Scene
from percept.drivers.sim.world import SimWorld
from percept.kinematics.camera import load_intrinsics
from percept.runtime.cli import main
from percept.runtime.settings.profile import load_profile
from percept.runtime.settings.scene import find_scene, load_scene
from tests.support.polling import wait_for

pytestmark = pytest.mark.timeout(120)

ROOT = Path(__file__).resolve().parents[3]
OP3 = ROOT / "config" / "robots" / "robotis-op3.toml"


@pytest.fixture(scope="module")
def nodding() -> SimWorld:
    """One OP3 whose head pans and tilts all the time, looking at a block."""
    data = {
        "name": "nodding",
        "robots": [
            {
                "name": "a",
                "profile": str(OP3),
                "pose": [-0.6, 0.1, 0.2],
                "joints": {
                    "head_pan": {"amplitude": 0.4, "period": 2.0},
                    "head_tilt": {"offset": -0.5, "amplitude": 0.2, "period": 3.0, "phase": 0.5},
                },
            }
        ],
        "objects": [{"id": 1, "shape": "block", "size": [0.05, 0.05, 0.1], "color": [0, 0, 220]}],
    }
    scene = build(Scene, data, ROOT / "config" / "scenes" / "nodding.toml")
    with SimWorld(scene, {"a": load_profile(OP3)}) as world:
        yield world


def test_sim_camera_hands_out_frame_k_at_scene_time_k_over_fps(nodding):
    settings = replace(load_profile(OP3).camera, source="sim", pace="lockstep", max_age=5.0)
    clock = StepClock()
    joints = SimJoints(nodding, "a", clock)
    assert isinstance(joints, JointSource)
    with SimCamera(nodding, "a", settings, clock) as camera:
        joints.start()
        frames = [camera.wait(timeout=10.0) for _ in range(4)]
        assert camera.status()["state"] == "connected"
    for k, frame in enumerate(frames):
        assert frame is not None and frame.seq == k
        scene_time = k / settings.fps
        assert np.array_equal(frame.image, nodding.render("a", scene_time))
        # joints read at the frame's time are the angles the frame was rendered with
        sample = joints.angles_at(frame.t)
        assert sample.angles == nodding.joint_angles("a", scene_time) and sample.age == 0.0
    assert frames[1].image.shape == (settings.height, settings.width, 3)
    assert not np.array_equal(frames[0].image, frames[3].image)  # the head moved
    joints.stop()
    assert joints.angles_at(time.monotonic()) is None


def test_a_held_wall_clock_shows_the_start_until_released(nodding):
    clock = WallClock(hold=True)
    assert clock.now() == 0.0
    clock.release()
    time.sleep(0.05)
    assert 0.04 < clock.now() < 5.0
    shared = WallClock(epoch=time.time() - 100.0)  # another process started 100 s ago
    assert shared.at(time.monotonic()) == pytest.approx(100.0, abs=0.5)
    assert shared.at(time.monotonic() - 1.0) == pytest.approx(99.0, abs=0.5)


def test_sim_camera_refuses_settings_that_do_not_fit_the_scene(nodding):
    settings = replace(load_profile(OP3).camera, width=640, height=480)
    with pytest.raises(ValueError, match="renders 320x200"):
        SimCamera(nodding, "a", settings)
    with pytest.raises(KeyError, match="no robot 'z'"):
        SimJoints(nodding, "z", StepClock())


def test_joint_angles_read_through_the_emulator_by_the_real_driver_are_the_truth(nodding):
    """The bridge sets the emulated servos to the simulated angles; the real DynamixelBus (on
    dynamixel-sdk, over a pty) reads them back within one encoder tick."""
    profile = load_profile(OP3)
    tick = {j.name: 2 * math.pi / j.ticks_per_rev for j in profile.joints}
    with ServoEmulator.for_profile(profile.joints, profile.bus.protocol) as emulator:
        bridge = EmulatorBridge(nodding, "a", emulator, StepClock())
        bus = DynamixelBus(replace(profile.bus, port=emulator.port_path), profile.joints)
        bus.start()
        try:
            for scene_time in (0.0, 0.37, 1.1, 2.45, 3.3):
                truth = nodding.joint_angles("a", scene_time)
                pushed = bridge.push(scene_time)
                assert set(pushed) == {"head_pan", "head_tilt"}
                since = time.monotonic()
                deadline = since + 10.0
                while time.monotonic() < deadline:
                    sample = bus.latest()
                    if sample is not None and sample.t > since + 0.02:
                        break
                    time.sleep(0.005)
                else:
                    pytest.fail(f"the bus read nothing: {bus.status()}")
                for joint, angle in sample.angles.items():
                    assert abs(angle - truth[joint]) <= tick[joint], (scene_time, joint)
            assert bus.status()["state"] == "connected"
        finally:
            bus.stop()


def test_the_bridge_keeps_the_emulated_servos_moving_with_the_scene(nodding):
    profile = load_profile(OP3)
    clock = WallClock(epoch=time.time())
    with ServoEmulator.for_profile(profile.joints, profile.bus.protocol) as emulator:
        bridge = EmulatorBridge(nodding, "a", emulator, clock, rate=200.0)
        bus = DynamixelBus(replace(profile.bus, port=emulator.port_path), profile.joints)
        bridge.start()
        bus.start()
        try:
            time.sleep(0.6)
            now = time.monotonic()
            for back in (0.1, 0.2, 0.3):
                t = now - back
                read = bus.angles_at(t).angles
                truth = nodding.joint_angles("a", clock.at(t))
                # a reading lags by the bridge period and a bus cycle: ~15 ms of head motion
                for joint in read:
                    assert abs(read[joint] - truth[joint]) < 0.02
            seen = {round(bus.angles_at(now - b).angles["head_pan"], 3) for b in (0.1, 0.3, 0.5)}
            assert len(seen) == 3  # the head really moves
        finally:
            bus.stop()
            bridge.stop()


def test_a_followed_joint_starts_where_the_scene_starts_whenever_the_bridge_starts(nodding):
    """The joints gaze moves start at the scene's time 0, however long the daemon took to
    start: from the running scene's keyframes they started anywhere in their motion (a demo's
    heads started, and came back after each look, 0.3-0.6 rad aside). The other joints still
    start with the scene as it is now."""
    profile = load_profile(OP3)
    late = 0.5  # s of scene time gone: the nodding pan is at its +0.4 rad peak, not at 0
    clock = WallClock(epoch=time.time() - late)
    with (
        SimWorld(nodding.scene, {"a": profile}) as world,
        ServoEmulator.for_profile(profile.joints, profile.bus.protocol) as emulator,
    ):
        bridge = EmulatorBridge(world, "a", emulator, clock, follow=("head_pan",))
        bridge.start()
        try:
            start, now = nodding.joint_angles("a", 0.0), nodding.joint_angles("a", late)
            assert abs(now["head_pan"] - start["head_pan"]) > 0.3  # the test can tell them apart
            tick = 2 * math.pi / 4096
            assert abs(emulator.angle("head_pan") - start["head_pan"]) <= tick
            assert abs(world.joint_angles("a", late)["head_pan"] - start["head_pan"]) <= tick
            # the tilt is not followed: it goes on with the scene (nodding, 0.2 rad over 3 s)
            assert abs(emulator.angle("head_tilt") - now["head_tilt"]) < 0.05
        finally:
            bridge.stop()


def test_with_gaze_the_simulated_head_follows_the_servos(nodding):
    """The loop closed through the bytes: the driver writes goals, the emulated servos move at
    their profile velocity, the simulated head follows them, not the scene's nodding."""
    profile = load_profile(OP3)
    gaze = GazeSettings(enabled=True, max_speed=2.0, watchdog=0.5)
    clock = WallClock(hold=True)  # scene time 0
    with (
        SimWorld(nodding.scene, {"a": profile}) as world,
        ServoEmulator.for_profile(profile.joints, profile.bus.protocol) as emulator,
    ):
        bridge = EmulatorBridge(world, "a", emulator, clock, follow=gaze.joints)
        settings = replace(profile.bus, port=emulator.port_path, timeout=0.1, stale_after=1.0)
        bus = DynamixelBus(settings, profile.joints, gaze=gaze)
        bridge.start()
        bus.start()
        try:
            start = nodding.joint_angles("a", 0.0)
            assert wait_for(lambda: bus.latest() is not None)
            assert abs(bus.latest().angles["head_tilt"] - start["head_tilt"]) < 0.01
            bus.engage()
            sent = bus.move({"head_pan": 0.5, "head_tilt": -0.3})
            assert wait_for(
                lambda: all(abs(emulator.angle(j) - a) < 1e-3 for j, a in sent.items()), 5.0
            )
            for scene_time in (0.0, 1.0):  # the bridge's next push puts them into the world
                assert wait_for(
                    lambda t=scene_time: all(
                        abs(world.joint_angles("a", t)[j] - sent[j]) < 1e-3 for j in sent
                    ),
                    5.0,
                )
            # The world's camera (MuJoCo's) is where FK puts it for the servos' angles.
            truth = world.truth(0.5, views=()).robots["a"].camera
            expected = world.robot_model("a").tree.camera_pose(sent)
            assert np.allclose(truth.R, expected.R, atol=2e-3)
            assert np.allclose(truth.t, expected.t, atol=1e-3)
            assert bus.status()["gaze"]["state"] == "on"
        finally:
            bus.stop()
            bridge.stop()


# -- percept sim ----------------------------------------------------------------------------


def test_percept_sim_writes_a_mot_sequence_with_truth(tmp_path):
    import motmetrics as mm

    out = tmp_path / "busy-a"
    start, seconds = 14.5, 1.0  # the green cuboid (4) is taken away at 15 s
    args = ["sim", "--scene", "tabletop-busy", "--robot", "a", "--out", str(out)]
    args += ["--start", str(start), "--seconds", str(seconds), "--fps", "10"]
    assert main(args) == 0
    info = configparser.ConfigParser()
    info.read(out / "seqinfo.ini")
    seq = info["Sequence"]
    assert (seq["imDir"], int(seq["seqLength"]), float(seq["frameRate"])) == ("img1", 10, 10.0)
    images = sorted((out / "img1").glob("*.png"))
    assert [p.name for p in images] == [f"{k:06d}.png" for k in range(1, 11)]
    records = [
        json.loads(line) for line in (out / "truth.jsonl").read_text(encoding="utf-8").splitlines()
    ]
    assert [r["frame"] for r in records] == list(range(1, 11))
    joints = (out / "joints.csv").read_text(encoding="utf-8").splitlines()
    assert joints[0] == "frame,t,head_pan,head_tilt" and len(joints) == 11
    scene, platforms = load_scene(find_scene("tabletop-busy"))
    lens = load_intrinsics(out / "intrinsics.json")
    with SimWorld(scene, platforms) as world:
        np.testing.assert_allclose(lens.K, world.camera_model("a").K)
        # the files hold exactly what the world renders and knows at those times
        t = start + 7 / 10
        assert np.array_equal(cv2.imread(str(images[7])), world.render("a", t))
        assert records[7] == {
            "frame": 8,
            **json.loads(json.dumps(world.truth(t, ["a"]).record("a"))),
        }
    gt = np.loadtxt(out / "gt" / "gt.txt", delimiter=",")
    assert gt.shape[1] == 10 and np.all(gt[:, 6:] == [1, -1, -1, -1])
    for record in records:
        rows = gt[gt[:, 0] == record["frame"]]
        visible = {o["id"] for o in record["objects"] if o["bbox"] and o["pixels"] >= 10}
        assert set(rows[:, 1].astype(int)) == visible
        for o in record["objects"]:
            if o["id"] in visible:
                row = rows[rows[:, 1] == o["id"]][0]
                assert list(row[2:6]) == [o["bbox"][0] + 1, o["bbox"][1] + 1, *o["bbox"][2:]]
        assert (4 in visible) == (record["t"] < 15.0)
    # a standard tool reads it: scored against itself, tracking is perfect
    truth = mm.io.loadtxt(str(out / "gt" / "gt.txt"), fmt="mot15-2D")
    acc = mm.MOTAccumulator(auto_id=True)
    for _, boxes in truth.groupby(level="FrameId"):
        ids = list(boxes.index.get_level_values("Id"))
        acc.update(ids, ids, 1.0 - np.eye(len(ids)))  # IoU distance of each box with itself
    summary = mm.metrics.create().compute(acc, metrics=["mota", "num_switches", "num_frames"])
    assert summary["mota"].iloc[0] == 1.0 and summary["num_switches"].iloc[0] == 0
    assert summary["num_frames"].iloc[0] == 10


def test_percept_sim_refuses_an_unknown_robot_or_scene(tmp_path, capsys):
    assert main(["sim", "--scene", "tabletop-basic", "--robot", "z", "--out", str(tmp_path)]) == 2
    assert "no robot 'z'" in capsys.readouterr().err
    assert main(["sim", "--scene", "no-such-scene", "--robot", "a", "--out", str(tmp_path)]) == 2
    assert "tabletop-basic" in capsys.readouterr().err  # the message lists the shipped scenes
