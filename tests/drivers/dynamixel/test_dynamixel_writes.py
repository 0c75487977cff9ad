"""Writes of the Dynamixel driver (gaze): the real driver and dynamixel-sdk against the emulator
on a pty, and the bytes of a SYNC WRITE on a bare pty against the e-Manual's examples."""

from __future__ import annotations

import functools
import logging
import math
import os
import select
import time
import tty
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest

from percept.config.loader import ConfigError
from percept.drivers.dynamixel.bus import DynamixelBus, radians_to_ticks, ticks_to_radians
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.errors import WriteFailed
from percept.drivers.dynamixel.link import Link
from percept.drivers.dynamixel.protocol import Instruction, decode
from percept.drivers.dynamixel.settings import GazeSettings, JointSettings
from percept.runtime.settings.experiment import check_gaze, load_experiment
from percept.runtime.settings.profile import load_profile
from tests.drivers.dynamixel.test_dynamixel import Rig as ReadRig
from tests.drivers.dynamixel.test_dynamixel import fast
from tests.support import head_limits
from tests.support.daemon import experiment_copy
from tests.support.polling import wait_for

pytestmark = pytest.mark.timeout(60)

PAN, TILT = "head_pan", "head_tilt"
JOINTS = {
    2.0: (
        JointSettings(PAN, 19, min=-1.57, max=1.57),
        JointSettings(TILT, 20, min=-1.2, max=0.6),
    ),
    1.0: (
        JointSettings(
            PAN, 3, model="AX-12A", ticks_per_rev=1228.8, zero_tick=512, sign=-1, min=-1.3, max=1.3
        ),
        JointSettings(TILT, 4, model="MX-28", min=-0.9, max=0.5),
    ),
}
until = functools.partial(wait_for, timeout=8.0)


def read_pty(fd: int, size: int, timeout: float = 2.0) -> bytes:
    got = b""
    end = time.monotonic() + timeout
    while len(got) < size and time.monotonic() < end:
        if select.select([fd], [], [], 0.05)[0]:
            got += os.read(fd, size - len(got))
    return got


@pytest.mark.parametrize(
    ("protocol", "address", "size", "data", "expected"),
    [
        # e-Manual, Protocol 2.0, Sync Write example: goal position (116) 150 to id 1, 170 to 2.
        (
            2.0,
            116,
            4,
            {1: (150).to_bytes(4, "little"), 2: (170).to_bytes(4, "little")},
            "FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87",
        ),
        # e-Manual, Protocol 1.0, Sync Write example: goal position and moving speed (30, 4
        # bytes) of ids 0-3.
        (
            1.0,
            30,
            4,
            {
                0: bytes.fromhex("10 00 50 01"),
                1: bytes.fromhex("20 02 60 03"),
                2: bytes.fromhex("30 00 70 01"),
                3: bytes.fromhex("20 02 80 03"),
            },
            "FF FF FE 18 83 1E 04 00 10 00 50 01 01 20 02 60 03 02 30 00 70 01 03 20 02 80 03 12",
        ),
    ],
    ids=["protocol2", "protocol1"],
)
def test_sync_write_bytes_on_the_pty_match_the_protocol(
    protocol: float, address: int, size: int, data: dict[int, bytes], expected: str
) -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    link = Link(os.ttyname(slave), 1_000_000, protocol, 0.02)
    try:
        link.sync_write(address, size, data)
        wire = read_pty(master, len(bytes.fromhex(expected)))
    finally:
        link.close()
        os.close(master)
        os.close(slave)
    assert wire == bytes.fromhex(expected)
    packet = decode(protocol, wire, status=False)
    assert packet.instruction == Instruction.SYNC_WRITE and packet.id == 0xFE


class Rig(ReadRig):
    """The read tests' rig, on a bus that may write."""

    def gaze(self) -> dict:
        return self.bus.status()["gaze"]

    def at(self, name: str, angle: float) -> bool:
        joint = self.joints[name]
        ticks = self.emu.register(joint.id, "present_position")
        return abs(ticks_to_radians(ticks, joint) - angle) <= 2 * math.pi / joint.ticks_per_rev

    def within_limits(self, name: str) -> bool:
        """Whether every goal the servo was ever given lies within the joint's min/max."""
        joint = self.joints[name]
        goals = self.emu.goals(joint.id)
        return all(joint.min <= ticks_to_radians(g, joint) <= joint.max for g in goals)


def open_rig(protocol: float, timeout: float = 0.1, **gaze: object) -> Rig:
    joints = JOINTS[protocol]
    emu = ServoEmulator(joints, protocol).start()
    emu.set_angle(PAN, 0.2)
    emu.set_angle(TILT, -0.1)
    # A long watchdog: the emulator, slowed by a loaded machine, must not see a bus gap.
    settings = GazeSettings(**{"enabled": True, "watchdog": 0.5, **gaze})  # type: ignore[arg-type]
    # Patient reads: a stale joint stops gaze, and on a loaded machine replies come late.
    bus_settings = replace(fast(protocol, emu.port_path), timeout=timeout, stale_after=1.0)
    bus = DynamixelBus(bus_settings, joints, gaze=settings)
    bus.start()
    return Rig(emu, bus, {j.name: j for j in joints}, protocol)


@pytest.fixture(params=[2.0, 1.0], ids=["protocol2", "protocol1"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    r = open_rig(request.param)
    try:
        assert until(lambda: r.bus.latest() is not None)
        yield r
    finally:
        r.bus.stop()
        r.emu.stop()


def test_nothing_is_written_until_engaged(rig: Rig) -> None:
    assert rig.gaze()["state"] == "off"
    with pytest.raises(ValueError, match="not a gaze joint"):
        rig.bus.move({"neck": 0.1})
    rig.bus.move({PAN: 0.5})  # not engaged: asked for, not sent
    time.sleep(0.2)
    assert "SYNC_WRITE" not in rig.emu.received and "WRITE" not in rig.emu.received
    for joint in rig.joints.values():
        assert rig.emu.register(joint.id, "torque_enable") == 0


def test_engage_holds_then_moves_with_one_sync_write_per_cycle(rig: Rig) -> None:
    rig.bus.engage()
    assert until(lambda: rig.gaze()["state"] == "on")
    for joint in rig.joints.values():
        assert rig.emu.register(joint.id, "torque_enable") == 1
    # The first goal is where the head already was: engaging does not make it jump.
    assert rig.emu.goals(rig.joints[PAN].id)[0] == radians_to_ticks(0.2, rig.joints[PAN])
    if rig.protocol == 2.0:  # 0.5 s in units of 20 ms
        assert rig.emu.register(rig.joints[PAN].id, "bus_watchdog") == 25
    sent = rig.bus.move({PAN: -0.4, TILT: 0.3}, speed=0.5)
    assert abs(sent[PAN] + 0.4) < 0.01 and abs(sent[TILT] - 0.3) < 0.01
    assert until(lambda: rig.at(PAN, sent[PAN]) and rig.at(TILT, sent[TILT]))
    speed = rig.joints[PAN].id, "profile_velocity" if rig.protocol == 2.0 else "moving_speed"
    assert rig.emu.register(*speed) >= 1  # never 0: that would be "as fast as it goes"
    # The goals go again every cycle (a lost broadcast is made good at the next).
    assert until(lambda: rig.emu.received["SYNC_WRITE"] > 5)
    assert abs(rig.gaze()["sync_writes"] - rig.emu.received["SYNC_WRITE"]) <= 1
    # Reads go on meanwhile, on the same thread.
    assert until(lambda: rig.bus.status()["reads_per_s"] > 10)


def test_writes_are_clipped_at_the_limits(rig: Rig) -> None:
    """A target behind the robot: the pan goal stops at its limit, whatever was asked."""
    rig.bus.engage()
    assert until(lambda: rig.gaze()["state"] == "on")
    pan, tilt = rig.joints[PAN], rig.joints[TILT]
    sent = rig.bus.move({PAN: math.pi, TILT: -3.0})
    assert pan.max - 0.01 < sent[PAN] <= pan.max and tilt.min <= sent[TILT] < tilt.min + 0.01
    assert until(lambda: rig.at(PAN, sent[PAN]) and rig.at(TILT, sent[TILT]))
    sent = rig.bus.move({PAN: -100.0, TILT: 100.0})
    assert pan.min <= sent[PAN] < pan.min + 0.01 and tilt.max - 0.01 < sent[TILT] <= tilt.max
    assert until(lambda: rig.at(PAN, sent[PAN]) and rig.at(TILT, sent[TILT]))
    with pytest.raises(ValueError, match="not a number"):
        rig.bus.move({PAN: math.nan})
    assert rig.within_limits(PAN) and rig.within_limits(TILT)
    assert len(rig.emu.goals(pan.id)) >= 3


def test_a_hardware_error_stops_gaze_and_is_reported(rig: Rig) -> None:
    rig.bus.engage()
    assert until(lambda: rig.gaze()["state"] == "on")
    tilt = rig.joints[TILT]
    rig.emu.set_hardware_error(tilt.id, 0x04)  # overheating, in both protocols
    assert until(lambda: rig.gaze()["state"] == "stopped")
    assert "head_tilt reports overheating" in rig.gaze()["problem"]
    time.sleep(0.1)  # the last sync write (holding the head) is on its way to the emulator
    before = rig.emu.received["SYNC_WRITE"]
    rig.bus.move({PAN: 0.9})
    time.sleep(0.3)
    assert rig.emu.received["SYNC_WRITE"] == before and rig.at(PAN, 0.2)
    # Asked again while the fault lasts: stopped again at once, nothing written.
    rig.bus.engage()
    time.sleep(0.3)
    assert rig.gaze()["state"] == "stopped" and rig.emu.received["SYNC_WRITE"] == before
    rig.emu.set_hardware_error(tilt.id, 0)
    assert until(lambda: rig.bus.status()["errors"] == {})
    rig.bus.engage()
    assert until(lambda: rig.gaze()["state"] == "on")
    rig.bus.move({PAN: 0.9})
    assert until(lambda: rig.at(PAN, 0.9))


def test_a_stale_joint_stops_gaze(rig: Rig) -> None:
    rig.bus.engage()
    assert until(lambda: rig.gaze()["state"] == "on")
    rig.emu.mute(rig.joints[PAN].id)
    assert until(lambda: rig.gaze()["state"] == "stopped")
    assert rig.gaze()["problem"].startswith("head_pan stale")
    time.sleep(0.1)  # the last sync write (holding the head) is on its way to the emulator
    before = rig.emu.goals(rig.joints[TILT].id)
    rig.bus.move({TILT: 0.4})
    time.sleep(0.3)
    assert rig.emu.goals(rig.joints[TILT].id) == before


@pytest.mark.parametrize("policy", ["hold", "release"])
@pytest.mark.parametrize("protocol", [2.0, 1.0], ids=["protocol2", "protocol1"])
def test_torque_policy_when_the_bus_stops(protocol: float, policy: str) -> None:
    r = open_rig(protocol, torque_at_stop=policy)
    try:
        r.bus.engage()
        assert until(lambda: r.gaze()["state"] == "on")
        r.bus.move({PAN: 0.6})
        assert until(lambda: r.at(PAN, 0.6))
        r.bus.stop()
        for joint in r.joints.values():
            assert r.emu.register(joint.id, "torque_enable") == (policy == "hold")
            if protocol == 2.0:
                assert r.emu.register(joint.id, "bus_watchdog") == 0
        assert r.at(PAN, 0.6)
    finally:
        r.bus.stop()
        r.emu.stop()


def test_a_watchdog_that_went_off_stops_gaze() -> None:
    """The emulator's bus watchdog goes off when the bus is silent; the driver notices (a sync
    write is never answered) and stops, and engages again after it was cleared."""
    r = open_rig(2.0, timeout=0.2, watchdog=0.06)
    try:
        r.bus.engage()
        assert until(lambda: r.gaze()["state"] == "on")
        pan = r.joints[PAN].id
        # A bus silent for longer than 60 ms as the emulator sees it (the driver waits for its
        # reply meanwhile).
        with r.emu._lock:
            time.sleep(0.1)
        assert until(lambda: r.gaze()["state"] == "stopped")
        assert "watchdog went off" in r.gaze()["problem"]
        r.bus.engage()
        assert until(lambda: r.gaze()["state"] == "on")
        assert r.emu.register(pan, "bus_watchdog") == 3
    finally:
        r.bus.stop()
        r.emu.stop()


def test_gaze_joints_must_have_servos() -> None:
    with pytest.raises(ValueError, match="three read periods"):
        DynamixelBus(fast(2.0, "/dev/null"), JOINTS[2.0], gaze=GazeSettings(watchdog=0.02))
    with pytest.raises(ValueError, match="gaze joint"):
        DynamixelBus(fast(2.0, "/dev/null"), JOINTS[2.0], gaze=GazeSettings(joints=("neck",)))
    narrow = (JointSettings(PAN, 19, min=0.0001, max=0.0002), JOINTS[2.0][1])
    with pytest.raises(ValueError, match="no encoder tick lies within"):
        DynamixelBus(fast(2.0, "/dev/null"), narrow, gaze=GazeSettings())
    with pytest.raises(ValueError, match="reading only"):
        DynamixelBus(fast(2.0, "/dev/null"), JOINTS[2.0]).engage()


def test_gaze_table_errors_name_file_and_key(tmp_path: Path) -> None:
    bad = experiment_copy(tmp_path, ('torque_at_stop = "hold"', 'torque_at_stop = "off"'))
    with pytest.raises(ConfigError, match=r"experiment.toml: gaze.torque_at_stop: expected"):
        load_experiment(bad)
    bad = experiment_copy(tmp_path, ("watchdog = 0.2", "watchdog = 5.0"))
    with pytest.raises(ConfigError, match=r"experiment.toml: gaze.watchdog: expected"):
        load_experiment(bad)
    good = experiment_copy(
        tmp_path,
        ('joints = ["head_pan", "head_tilt"]', 'joints = ["neck"]'),
        ("enabled = false", "enabled = true"),
    )
    experiment = load_experiment(good)
    with pytest.raises(
        ConfigError, match=r"experiment.toml: gaze.joints: neck: not a servo of profile"
    ):
        check_gaze(good, experiment, load_profile("robotis-op3"))


# -- the emulator moves ----------------------------------------------------------------------


def put(link: Link, servo: int, address: int, value: int, size: int) -> None:
    link.write(servo, address, value.to_bytes(size, "little"))


def test_emulated_servo_moves_at_its_profile_velocity() -> None:
    with ServoEmulator(JOINTS[2.0], 2.0) as emu:
        link = Link(emu.port_path, 1_000_000, 2.0, 0.2)
        try:
            # 100 units of 0.229 rpm: 2.398 rad/s, 1563 ticks/s; 1000 ticks take 0.64 s.
            put(link, 19, 112, 100, 4)
            put(link, 19, 116, 3048, 4)
            time.sleep(0.1)  # torque off: the goal is taken, the shaft stays
            assert emu.register(19, "present_position") == 2048
            rate = 100 * 0.229 / 60 * 4096  # ticks per second
            before = time.monotonic()
            put(link, 19, 64, 1, 1)
            began = time.monotonic()  # torque went on between before and began
            time.sleep(0.3)
            looked = time.monotonic()
            ticks = emu.register(19, "present_position")
            assert 2048 + rate * (looked - began) - 1 <= ticks
            assert ticks <= 2048 + rate * (time.monotonic() - before) + 1
            assert wait_for(lambda: emu.register(19, "present_position") == 3048, timeout=3)
            # present_position is rounded: it shows the goal half a tick before the shaft is there
            assert time.monotonic() - before > 999.5 / rate
            # Torque off in the middle of a move: it stays where it is.
            put(link, 19, 116, 1048, 4)
            time.sleep(0.2)
            put(link, 19, 64, 0, 1)
            stopped = emu.register(19, "present_position")
            assert 1048 < stopped < 3048 - 200
            time.sleep(0.2)
            assert emu.register(19, "present_position") == stopped
        finally:
            link.close()


def test_emulated_watchdog_stops_a_moving_servo() -> None:
    with ServoEmulator(JOINTS[2.0], 2.0) as emu:
        link = Link(emu.port_path, 1_000_000, 2.0, 0.2)
        try:
            put(link, 19, 64, 1, 1)
            put(link, 19, 98, 5, 1)  # 100 ms
            put(link, 19, 112, 50, 4)  # 782 ticks/s
            put(link, 19, 116, 4000, 4)
            time.sleep(0.5)  # nothing on the bus
            # It went 0.1 s (about 78 ticks) and stopped: not the 390 ticks of 0.5 s.
            ticks = emu.register(19, "present_position")
            assert 2048 + 40 < ticks < 2048 + 78 + 40, ticks
            assert emu.register(19, "bus_watchdog") == 0xFF
            assert emu.register(19, "goal_position") == ticks
            # Goals are refused until the watchdog is written 0.
            with pytest.raises(WriteFailed, match="refused"):
                put(link, 19, 116, 4000, 4)
            with pytest.raises(WriteFailed, match="refused"):
                put(link, 19, 98, 5, 1)
            put(link, 19, 98, 0, 1)
            put(link, 19, 116, 2500, 4)
        finally:
            link.close()


# -- readings that are no place to go --------------------------------------------------------

# Tick 100 in a valid reply: head_pan at -2.99 rad on the X series (limits +-1.57), +2.11 rad on
# the AX-12A (limits +-1.3).
WRONG = 100


def outside(rig: Rig) -> dict[str, list[float]]:
    """Goals outside the joint's limits, by the emulator's log of every goal its servos took."""
    out = {}
    for name, joint in rig.joints.items():
        angles = [ticks_to_radians(g, joint) for g in rig.emu.goals(joint.id)]
        bad = [round(a, 3) for a in angles if not joint.min <= a <= joint.max]
        if bad:
            out[name] = bad
    return out


def engaged(rig: Rig) -> None:
    rig.bus.engage()
    assert until(lambda: rig.gaze()["state"] == "on")


def test_an_impossible_reading_is_not_held_at_stop(rig: Rig) -> None:
    engaged(rig)
    rig.emu.glitch(rig.joints[PAN].id, WRONG)
    assert until(lambda: rig.bus.status()["bad_readings"] > 0)
    rig.bus.stop()  # holds the head: at the last good reading, not at the glitch
    time.sleep(0.3)
    assert outside(rig) == {} and rig.at(PAN, 0.2)
    assert rig.emu.register(rig.joints[PAN].id, "torque_enable") == 1


def test_an_impossible_reading_is_not_held_on_a_fault(rig: Rig) -> None:
    engaged(rig)
    rig.emu.glitch(rig.joints[PAN].id, WRONG)
    tilt = rig.joints[TILT].id
    rig.emu.mute(tilt)
    time.sleep(0.6)
    rig.emu.mute(tilt, False)
    assert until(lambda: rig.gaze()["state"] == "stopped")
    # Whichever the reader met first, the glitch or the mute, stopped it.
    assert rig.gaze()["problem"].startswith((PAN, TILT))
    time.sleep(0.3)
    assert outside(rig) == {} and rig.at(PAN, 0.2)


def test_an_impossible_reading_is_not_held_at_engage(rig: Rig) -> None:
    rig.emu.glitch(rig.joints[PAN].id, WRONG)
    # The first such reply is a jump, dropped; the ones after it agree, and are outside.
    assert until(lambda: "outside" in rig.bus.status()["reading_faults"].get(PAN, ""))
    rig.bus.engage()
    assert until(lambda: rig.gaze()["state"] == "stopped")
    assert "outside its limits" in rig.gaze()["problem"]
    time.sleep(0.3)
    assert outside(rig) == {} and rig.at(PAN, 0.2)
    for joint in rig.joints.values():
        assert rig.emu.register(joint.id, "torque_enable") == 0
    rig.emu.clear_faults()
    assert until(lambda: not rig.bus.status()["reading_faults"])
    engaged(rig)  # the glitch is over: asked again, it engages where the head is
    assert outside(rig) == {} and rig.at(PAN, 0.2)


def test_a_head_outside_its_limits_is_not_engaged(rig: Rig) -> None:
    rig.emu.set_angle(TILT, 1.0)  # above the tilt's max: 0.6 (X series), 0.5 (MX-28)
    assert until(lambda: abs(rig.bus.latest().angles[TILT] - 1.0) < 0.01)  # type: ignore[union-attr]
    rig.bus.engage()
    assert until(lambda: rig.gaze()["state"] == "stopped")
    assert rig.gaze()["problem"].startswith(f"{TILT} reads +1.0")
    assert "outside its limits" in rig.gaze()["problem"]
    time.sleep(0.3)
    assert outside(rig) == {} and rig.at(TILT, 1.0)
    for joint in rig.joints.values():
        assert rig.emu.register(joint.id, "torque_enable") == 0
    rig.emu.set_angle(TILT, 0.3)  # put back inside by hand
    assert until(lambda: not rig.bus.status()["reading_faults"])
    engaged(rig)
    assert outside(rig) == {} and rig.at(TILT, 0.3)


def test_a_reading_beyond_a_revolution_or_a_jump_is_not_taken(
    rig: Rig, caplog: pytest.LogCaptureFixture
) -> None:
    pan = rig.joints[PAN]
    caplog.set_level(logging.INFO, logger="percept.dynamixel")
    # Beyond a revolution from the zero (X series: a signed register; AX: 2 bytes unsigned).
    rig.emu.glitch(pan.id, -10_000 if rig.protocol == 2.0 else 60_000, replies=1)
    assert until(lambda: rig.bus.status()["bad_readings"] == 1)
    time.sleep(1.0)  # the log says it at most once a second
    # To the other limit for one reply: no servo turns that fast.
    rig.emu.glitch(pan.id, radians_to_ticks(-1.2, pan), replies=1)
    assert until(lambda: rig.bus.status()["bad_readings"] >= 2)
    time.sleep(0.1)
    assert until(lambda: rig.bus.status()["reading_faults"] == {})  # good readings since
    logged = caplog.text
    assert "beyond a revolution" in logged and "faster than it can turn" in logged
    # Neither went into the history the camera poses come from.
    now = time.monotonic()
    seen = [rig.bus.angles_at(now - k * 0.005) for k in range(100)]
    assert all(abs(s.angles[PAN] - 0.2) < 0.01 for s in seen if s is not None)


def test_the_port_lost_fault_lasts_while_the_port_is_gone(rig: Rig) -> None:
    engaged(rig)
    rig.emu.unplug()
    assert until(lambda: "port lost" in (rig.gaze()["problem"] or ""))
    problem = rig.gaze()["problem"]
    rig.bus.engage()  # a look asks again, as gaze does after a stop
    time.sleep(1.0)
    assert rig.gaze()["state"] == "stopped" and rig.gaze()["problem"] == problem
    rig.emu.replug()
    assert until(lambda: rig.bus.status()["state"] == "connected")
    engaged(rig)
    assert outside(rig) == {}


@pytest.mark.parametrize("protocol", [2.0, 1.0], ids=["protocol2", "protocol1"])
def test_no_goal_outside_the_limits_over_glitched_muted_unplugged_cycles(protocol: float) -> None:
    """400 read periods, a fault starting in one in twenty (bench/limits.py: 10,000)."""
    outcome = head_limits.run(400, protocol, seed=36, fault_rate=0.05)
    assert outcome.outside == {}
    assert outcome.stops >= 2 and outcome.bad_readings > 0  # the faults did stop the head
    # Engaged and sent goals in between (fewer on a loaded machine: stale reads stop it too).
    assert len(outcome.injected) == len(head_limits.FAULTS) and min(outcome.goals.values()) > 20


@pytest.mark.parametrize("protocol", [2.0, 1.0], ids=["protocol2", "protocol1"])
def test_a_fault_releases_the_head_when_the_torque_policy_says_so(protocol: float) -> None:
    r = open_rig(protocol, torque_at_stop="release")
    try:
        assert until(lambda: r.bus.latest() is not None)
        engaged(r)
        r.emu.glitch(r.joints[PAN].id, WRONG)
        assert until(lambda: r.gaze()["state"] == "stopped")
        for joint in r.joints.values():
            assert until(lambda joint=joint: r.emu.register(joint.id, "torque_enable") == 0)
        assert outside(r) == {}
    finally:
        r.bus.stop()
        r.emu.stop()
