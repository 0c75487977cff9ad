"""Gaze behaviours over the real driver and dynamixel-sdk, against the emulated servos on a pty
(which move at their profile velocity)."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from percept.drivers.dynamixel.bus import DynamixelBus, ticks_to_radians
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.settings import GazeSettings
from percept.kinematics.gaze import Unreachable, off_axis
from percept.kinematics.pose import CameraPose
from percept.kinematics.tree import KinematicTree
from percept.runtime.daemon.daemon import Daemon
from percept.runtime.daemon.gaze import CalibrationSweep, Gaze
from percept.runtime.daemon.settings import DaemonOptions
from percept.runtime.net.messages import document
from percept.runtime.settings.experiment import load_experiment
from percept.runtime.settings.profile import PlatformProfile, load_profile
from percept.runtime.settings.scene import find_scene
from tests.support.daemon import experiment_copy
from tests.support.polling import wait_for

pytestmark = pytest.mark.timeout(60)


@dataclass
class Rig:
    emu: ServoEmulator
    bus: DynamixelBus
    gaze: Gaze
    profile: PlatformProfile

    def within_limits(self) -> bool:
        for joint in self.profile.joints:
            goals = self.emu.goals(joint.id)
            if not all(joint.min <= ticks_to_radians(g, joint) <= joint.max for g in goals):
                return False
        return True


@pytest.fixture(params=["robotis-op3", "myon"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    profile = load_profile(request.param)
    settings = GazeSettings(enabled=True, max_speed=3.0, watchdog=0.5)
    emu = ServoEmulator.for_profile(profile.joints, profile.bus.protocol).start()
    bus_settings = replace(profile.bus, port=emu.port_path, timeout=0.1, stale_after=1.0)
    bus = DynamixelBus(bus_settings, profile.joints, gaze=settings)
    bus.start()
    tree = KinematicTree.from_settings(profile.kinematics)
    try:
        assert wait_for(lambda: bus.latest() is not None)
        yield Rig(emu, bus, Gaze(bus, tree, profile.joints, settings), profile)
    finally:
        bus.stop()
        emu.stop()


def read_angles(rig: Rig) -> dict[str, float]:
    sample = rig.bus.latest()
    assert sample is not None
    return sample.angles


def test_look_at_settles_with_the_axis_on_the_target(rig: Rig) -> None:
    for target in [(1.2, 0.5, 0.0), (1.5, -0.8, 0.0), (2.0, 0.0, 0.3)]:
        rig.gaze.look_at(*target)
        assert rig.gaze.wait_settled(10.0), rig.gaze.status()
        # Read back through the driver: off by encoder quantisation (0.09 deg) at most.
        error = off_axis(rig.gaze.tree, read_angles(rig), target)
        assert math.degrees(error) < 0.5, (target, math.degrees(error))
        status = rig.gaze.status()
        assert status["target"] == list(target) and status["behaviour"] == "look_at"
        assert status["state"] == "on" and status["settled"]
    assert rig.within_limits()


def test_a_target_behind_is_refused_and_nothing_moves(rig: Rig) -> None:
    with pytest.raises(Unreachable, match="outside the head's range"):
        rig.gaze.look_at(-1.0, 0.1)
    assert "SYNC_WRITE" not in rig.emu.received
    assert rig.gaze.status()["refused"].startswith("target (-1.000, 0.100, 0.000)")
    assert rig.gaze.status()["state"] == "off"


def test_sweep_visits_the_working_range_back_and_forth(rig: Rig) -> None:
    fixations = rig.gaze.sweep(pan=(-0.6, 0.6), tilt=(-0.5, -0.2), steps=(3, 2))
    pans = [round(f.goals["head_pan"], 3) for f in fixations]
    assert pans == [-0.6, 0.0, 0.6, 0.6, 0.0, -0.6]
    assert [round(f.goals["head_tilt"], 3) for f in fixations] == [-0.5] * 3 + [-0.2] * 3
    whole = rig.gaze.sweep()
    pan = rig.profile.joint("head_pan")
    assert min(f.goals["head_pan"] for f in whole) == pan.min
    assert max(f.goals["head_pan"] for f in whole) == pan.max
    reached = rig.gaze.run(fixations, dwell=0.0, stop=threading.Event(), behaviour="sweep")
    assert reached == len(fixations)
    assert abs(read_angles(rig)["head_pan"] + 0.6) < 0.01
    assert rig.within_limits()


def test_scan_leaves_out_what_it_cannot_face_and_look_at_peer(rig: Rig) -> None:
    fixations, refused = rig.gaze.scan([(1.5, 0.3, 0.0), (-1.0, 0.0, 0.0), (1.5, -0.3, 0.0)])
    assert [f.target for f in fixations] == [(1.5, 0.3, 0.0), (1.5, -0.3, 0.0)]
    assert len(refused) == 1 and "(-1.000, 0.000, 0.000)" in refused[0]
    assert rig.gaze.run(fixations, 0.05, threading.Event(), "scan") == 2
    # The peer 1.5 m away to the left: at eye height, the camera looks level at it.
    rig.gaze.look_at_peer(1.0, 1.0)
    assert rig.gaze.wait_settled(10.0)
    eye = rig.gaze.eye_height()
    assert math.degrees(off_axis(rig.gaze.tree, read_angles(rig), (1.0, 1.0, eye))) < 0.5


def test_a_servo_fault_ends_a_behaviour(rig: Rig) -> None:
    fixations = rig.gaze.sweep(steps=(9, 3))
    rig.emu.set_hardware_error(rig.profile.joint("head_tilt").id, 0x04)
    reached = rig.gaze.run(fixations, 0.0, threading.Event(), "sweep")
    assert reached < len(fixations)
    status = rig.gaze.status()
    assert status["state"] == "stopped" and "overheating" in status["problem"]


def test_the_calibration_sweep_waits_until_every_gaze_joint_is_read() -> None:
    """Planned from a servo that has not answered yet, the sweep would take it for 0 and leave
    the head there: it is planned once the bus has read every gaze joint, at their angles."""
    profile = load_profile("robotis-op3")
    settings = GazeSettings(enabled=True, max_speed=3.0, watchdog=0.5)
    tilt = next(j for j in profile.joints if j.name == "head_tilt")
    with ServoEmulator.for_profile(profile.joints, profile.bus.protocol) as emu:
        emu.set_angle("head_tilt", -0.4)
        emu.mute(tilt.id)  # the tilt servo does not answer at first
        bus_settings = replace(profile.bus, port=emu.port_path, timeout=0.1, stale_after=1.0)
        bus = DynamixelBus(bus_settings, profile.joints, gaze=settings)
        bus.start()
        tree = KinematicTree.from_settings(profile.kinematics)
        gaze = Gaze(bus, tree, profile.joints, settings)
        sweep = CalibrationSweep(gaze)
        stop = threading.Event()
        try:
            assert wait_for(lambda: bus.latest() is not None)  # the pan is read
            assert not gaze.knows_head()
            sweep.start()
            time.sleep(0.5)
            assert not sweep.fixations  # not planned yet
            emu.mute(tilt.id, False)
            assert wait_for(lambda: bool(sweep.fixations), 10)
            tilts = [f.goals["head_tilt"] for f in sweep.fixations]
            assert tilts == pytest.approx([-0.4] * len(tilts), abs=0.01)
        finally:
            stop.set()
            sweep.finish(stop)
            bus.stop()


def test_a_calibration_sweep_cut_short_turns_the_head_back(rig: Rig) -> None:
    """A sweep that runs out of its time (fixations tried again on a busy machine) must not
    leave the head wherever it got to: it turns back to where it was."""
    start = read_angles(rig)["head_pan"]
    sweep = CalibrationSweep(rig.gaze, dwell=1.0)
    stop = threading.Event()
    sweep.start()
    # Past the middle of the sweep, where the head started: it turns away again.
    assert wait_for(lambda: sweep.reached >= 3, 15)
    sweep.began -= 2 * sweep.duration + 1.0  # as if its time had run out
    sweep.finish(stop)
    assert sweep.reached < len(sweep.fixations)
    assert rig.gaze.wait_settled(10.0)
    assert abs(read_angles(rig)["head_pan"] - start) < 0.01
    assert rig.within_limits()


def test_a_turn_back_refused_by_a_fault_is_tried_again(rig: Rig) -> None:
    """The fault that cut a sweep short (a servo that stops answering for a moment on a busy
    machine) is often still there when the head should turn back: tried once, the turn back
    failed and the head looked aside for the whole run. It is tried again once the servo
    answers."""
    start = read_angles(rig)["head_pan"]
    pan = rig.profile.joint("head_pan")
    sweep = CalibrationSweep(rig.gaze, dwell=1.0)
    stop = threading.Event()
    sweep.start()
    assert wait_for(lambda: sweep.reached >= 2, 15)  # at one end of the pan range
    rig.emu.mute(pan.id)  # stale after 1 s: gaze stops, the turn back with it
    answers = threading.Timer(1.5, rig.emu.mute, (pan.id, False))
    answers.start()
    try:
        sweep.began -= 2 * sweep.duration + 1.0  # as if its time had run out
        sweep.finish(stop)
        assert sweep.reached < len(sweep.fixations)
        assert wait_for(lambda: abs(read_angles(rig)["head_pan"] - start) < 0.01, 10)
        assert rig.within_limits()
    finally:
        answers.cancel()
        rig.emu.mute(pan.id, False)


def test_the_calibration_sweep_engages_the_head_once_the_kernels_are_loaded(rig: Rig) -> None:
    """Loading the kernels keeps the servo bus's thread from running long enough for the bus
    watchdog to stop a head just engaged: the sweep is planned and run after the warm-up."""
    from percept.perception.warm import warm_up_in_background, warming

    thread = warm_up_in_background()
    sweep = CalibrationSweep(rig.gaze, dwell=0.0)
    stop = threading.Event()
    sweep.start()
    try:
        while thread.is_alive():
            # Planned (read first) while a warm-up still runs (read after): planned too early.
            assert not (sweep.fixations and warming())
            time.sleep(0.01)
        assert wait_for(lambda: bool(sweep.fixations), 10)
    finally:
        stop.set()
        sweep.finish(stop)


def optical_axis_error(camera: CameraPose, target: tuple[float, float, float]) -> float:
    """Degrees between a camera pose's optical axis (x) and the direction to ``target``."""
    d = np.asarray(target) - camera.t
    cosine = float(camera.R[:, 0] @ d / np.linalg.norm(d))
    return math.degrees(math.acos(max(-1.0, min(1.0, cosine))))


def simulated_robot_a(experiment: Path) -> DaemonOptions:
    """``percept run --sim`` of robot a of ``experiment`` in ``tabletop-basic``."""
    return DaemonOptions(
        robot="a",
        profile_path=load_experiment(experiment).robot("a").profile,
        experiment_path=experiment,
        sim_scene=str(find_scene("tabletop-basic")),
    )


@pytest.mark.timeout(120)
def test_the_daemon_in_simulation_looks_at_a_point_through_the_real_bytes(tmp_path: Path) -> None:
    """``percept run --sim`` with gaze enabled: the daemon's gaze writes goals on the bus, the
    emulated servos move, the simulated head follows them; the rendered camera (MuJoCo's, the
    truth) then looks at the target, and the status says so."""
    # A long watchdog: on a loaded test machine the daemon's threads can starve the bus's.
    experiment = experiment_copy(
        tmp_path, ("enabled = false", "enabled = true"), ("watchdog = 0.2", "watchdog = 1.0")
    )
    options = simulated_robot_a(experiment)
    daemon = Daemon(options)
    try:
        daemon.start()
        assert daemon.gaze is not None
        assert wait_for(lambda: daemon.devices.joints.latest() is not None, 30)
        # With gaze the daemon sweeps the head over its pan range while it calibrates the
        # background, and brings it back; then it is idle, looking at nothing in particular.
        assert document(daemon.status())["gaze"]["behaviour"] in ("sweep", "idle")
        assert wait_for(
            lambda: document(daemon.status())["background"].startswith("calibrated"), 60
        )
        before = document(daemon.status())["gaze"]
        assert before["enabled"] and before["behaviour"] == "idle" and before["target"] is None
        # From now on the pointing games look (not during the sweep).
        assert wait_for(lambda: daemon.games is not None and daemon.games.looker is not None, 10)
        target = (0.9, 0.35, 0.0)
        # A stale joint (the emulator starved by the perception thread on a loaded machine)
        # stops gaze; the next look engages it again (README, Failure behaviour).
        for _ in range(5):
            daemon.gaze.look_at(*target)
            engaged = wait_for(lambda: daemon.gaze.status()["state"] != "off", 5.0)
            if engaged and daemon.gaze.wait_settled(15.0):
                break
            time.sleep(0.5)  # the stale joint answers again
        assert daemon.gaze.settled(), daemon.gaze.status()
        world = daemon.devices.camera.world

        def error() -> float:
            truth = world.truth(daemon.devices.clock.now(), views=()).robots["a"].camera
            return optical_axis_error(truth, target)

        # The bridge's next push puts the servos' angles into the world.
        assert wait_for(lambda: error() < 1.0, 5.0), error()
        status = document(daemon.status())  # the status as it is sent
        assert status["gaze"]["state"] == "on" and status["gaze"]["target"] == list(target)
        assert status["gaze"]["settled"] and status["servos"]["gaze"]["state"] == "on"
        assert not [f for f in status["faults"] if f.startswith("gaze")]
    finally:
        daemon.stop()


def test_a_sweep_longer_than_its_limit_is_refused_at_start(tmp_path: Path) -> None:
    """At max_speed 0.01 rad/s (allowed) the calibration sweep of the OP3's pan (+-1.57 rad)
    would take 630 s with no world model: the daemon refuses before anything opens."""
    from percept.config.loader import ConfigError
    from percept.runtime.daemon.gaze import SWEEP_LIMIT, check_sweep, sweep_seconds

    slow = experiment_copy(
        tmp_path, ("enabled = false", "enabled = true"), ("max_speed = 1.0", "max_speed = 0.01")
    )
    options = simulated_robot_a(slow)
    with pytest.raises(ConfigError, match=r"experiment.toml: gaze.max_speed: 0.01 rad/s") as err:
        Daemon(options)
    assert "take 630 s" in str(err.value) and "0.11 rad/s or more" in str(err.value)
    # The shipped speed sweeps in 8 s; with a saved background there is no sweep to refuse.
    profile = load_profile("robotis-op3")
    pan = next(j for j in profile.joints if j.name == "head_pan")
    assert sweep_seconds(pan, 1.0) < 10.0 < SWEEP_LIMIT
    check_sweep(slow, GazeSettings(max_speed=0.11), profile.joints)
