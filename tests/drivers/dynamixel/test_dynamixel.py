"""The real Dynamixel driver and the real dynamixel-sdk against the byte-level emulator on a pty:
both protocols, every injected fault, and the two CLI commands as separate processes."""

from __future__ import annotations

import functools
import json
import math
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import dynamixel_sdk as sdk
import pytest

from percept.drivers.dynamixel.bus import DynamixelBus, radians_to_ticks
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.errors import ReadFailed
from percept.drivers.dynamixel.link import Link
from percept.drivers.dynamixel.models import find_model
from percept.drivers.dynamixel.settings import BusSettings, JointSettings
from percept.runtime.settings.profile import load_profile
from tests.support.polling import wait_for

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[3]
PAN, TILT = "head_pan", "head_tilt"
JOINTS = {
    2.0: (JointSettings(PAN, 19), JointSettings(TILT, 20)),
    1.0: (
        JointSettings(PAN, 3, model="AX-12A", ticks_per_rev=1228.8, zero_tick=512, sign=-1),
        JointSettings(TILT, 4, model="MX-28"),
    ),
}
START = {PAN: 0.3, TILT: -0.2}


@pytest.fixture(autouse=True)
def patient_sdk(monkeypatch: pytest.MonkeyPatch) -> None:
    """The SDK waits for a reply two USB latency timers (16 ms each, an FTDI adapter's) and
    2 ms: a pty has no such timer, but the emulator's thread may be that late on a loaded
    machine, and the SDK then reports a timeout that is the test machine's, not the protocol's.
    """
    monkeypatch.setattr(sdk.port_handler, "LATENCY_TIMER", 250)


def fast(protocol: float, port: str) -> BusSettings:
    """Short timeouts and intervals so faults show within a fraction of a second."""
    return BusSettings(
        port=port,
        protocol=protocol,
        timeout=0.02,
        rate=100.0,
        retries=2,
        stale_after=0.15,
        error_poll_interval=0.05,
        probe_interval=0.05,
        reconnect_backoff=(0.02, 0.1),
    )


until = functools.partial(wait_for, timeout=8.0)


@dataclass
class Rig:
    emu: ServoEmulator
    bus: DynamixelBus
    joints: dict[str, JointSettings]
    protocol: float

    def tick(self, name: str) -> float:
        return 2 * math.pi / self.joints[name].ticks_per_rev

    def reads(self, name: str, angle: float) -> bool:
        """Whether the newest reading of ``name`` is ``angle`` (within a tick) and not stale."""
        sample = self.bus.angles_at(time.monotonic())
        return (
            sample is not None
            and name not in sample.stale
            and name in sample.angles
            and abs(sample.angles[name] - angle) <= self.tick(name)
            and self.bus.status()["state"] == "connected"
        )

    def seen(self, name: str, since: float) -> list[float]:
        """The angle of ``name`` at every 2 ms since ``since``, from the driver's history."""
        now = time.monotonic()
        steps = int((now - since) / 0.002)
        found = []
        for k in range(steps):
            sample = self.bus.angles_at(since + k * 0.002)
            if sample is not None and name in sample.angles:
                found.append(sample.angles[name])
        return found

    def failures(self) -> int:
        """Read attempts that failed so far, retried or not."""
        status = self.bus.status()
        return status["retries"] + status["failed_reads"]

    def only_ever(self, name: str, angle: float, since: float) -> bool:
        values = self.seen(name, since)
        return bool(values) and all(abs(v - angle) <= self.tick(name) for v in values)


@pytest.fixture(params=[2.0, 1.0], ids=["protocol2", "protocol1"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    protocol = request.param
    joints = JOINTS[protocol]
    emu = ServoEmulator(joints, protocol).start()
    for name, angle in START.items():
        emu.set_angle(name, angle)
    bus = DynamixelBus(fast(protocol, emu.port_path), joints)
    bus.start()
    r = Rig(emu, bus, {j.name: j for j in joints}, protocol)
    try:
        assert until(lambda: r.reads(PAN, START[PAN]) and r.reads(TILT, START[TILT]))
        yield r
    finally:
        bus.stop()
        emu.stop()


def test_reads_angles_and_follows_them(rig: Rig) -> None:
    rig.emu.set_angle(PAN, -0.7)
    rig.emu.set_angle(TILT, 0.45)
    assert until(lambda: rig.reads(PAN, -0.7) and rig.reads(TILT, 0.45))
    status = rig.bus.status()
    assert status["stale"] == [] and status["errors"] == {} and status["reconnects"] == 0
    assert until(lambda: rig.bus.status()["reads_per_s"] > 10)
    # Interpolated between readings: a time between two readings gets an angle between them.
    sample = rig.bus.angles_at(time.monotonic() - 0.05)
    assert sample is not None and sample.age == 0.0
    # Protocol 2.0 reads with sync read, 1.0 servo by servo; nothing is ever written.
    reads = {"SYNC_READ", "READ"} if rig.protocol == 2.0 else {"READ"}
    assert set(rig.emu.received) == reads
    for joint in rig.joints.values():
        assert rig.emu.register(joint.id, "torque_enable") == 0


def test_mute_servo_goes_stale_others_keep_reading(rig: Rig) -> None:
    since = time.monotonic()
    tilt = rig.joints[TILT]
    rig.emu.mute(tilt.id)
    assert until(lambda: rig.bus.status()["stale"] == [TILT])
    sample = rig.bus.angles_at(time.monotonic())
    assert sample is not None and sample.stale == frozenset({TILT}) and sample.age > 0.15
    rig.emu.set_angle(PAN, 0.9)
    assert until(lambda: rig.reads(PAN, 0.9))
    # The silent servo's joint keeps its last real angle; a failed read is never an angle.
    assert rig.only_ever(TILT, START[TILT], since)
    rig.emu.mute(tilt.id, False)
    rig.emu.set_angle(TILT, 0.1)
    assert until(lambda: rig.reads(TILT, 0.1) and rig.bus.status()["stale"] == [])


def test_one_corrupt_reply_is_refused_and_reading_goes_on(rig: Rig) -> None:
    since = time.monotonic()
    before = rig.failures()
    rig.emu.corrupt(rig.joints[TILT].id, replies=1)
    assert until(lambda: rig.failures() > before)
    assert until(lambda: rig.reads(TILT, START[TILT]))
    assert rig.only_ever(TILT, START[TILT], since)


def test_corrupt_replies_make_the_joint_stale_never_a_wrong_angle(rig: Rig) -> None:
    since = time.monotonic()
    rig.emu.corrupt(rig.joints[TILT].id)
    assert until(lambda: TILT in rig.bus.status()["stale"])
    rig.emu.set_angle(PAN, -0.4)
    assert until(lambda: rig.reads(PAN, -0.4))
    assert rig.bus.status()["failed_reads"] > 0
    assert rig.only_ever(TILT, START[TILT], since)
    rig.emu.clear_faults()
    assert until(lambda: rig.reads(TILT, START[TILT]))


def test_short_replies_are_refused(rig: Rig) -> None:
    since = time.monotonic()
    tilt = rig.joints[TILT].id
    before = rig.failures()
    rig.emu.short_reply(tilt, replies=1)
    assert until(lambda: rig.failures() > before)
    rig.emu.short_reply(tilt)
    assert until(lambda: TILT in rig.bus.status()["stale"])
    assert rig.only_ever(TILT, START[TILT], since)
    rig.emu.clear_faults(tilt)
    assert until(lambda: rig.reads(TILT, START[TILT]))


def test_hardware_error_is_reported(rig: Rig) -> None:
    tilt = rig.joints[TILT].id
    rig.emu.set_hardware_error(tilt, 0x04)
    assert until(lambda: rig.bus.status()["errors"] == {TILT: ["overheating"]})
    # The servo still answers: its joint stays fresh.
    rig.emu.set_angle(TILT, 0.25)
    assert until(lambda: rig.reads(TILT, 0.25))
    rig.emu.set_hardware_error(tilt, 0)
    assert until(lambda: rig.bus.status()["errors"] == {})


def test_reply_later_than_the_timeout(rig: Rig) -> None:
    since = time.monotonic()
    tilt = rig.joints[TILT].id
    rig.emu.delay(tilt, 0.1)  # the bus waits 0.02 s
    assert until(lambda: TILT in rig.bus.status()["stale"])
    rig.emu.set_angle(PAN, 0.6)
    assert until(lambda: rig.reads(PAN, 0.6))
    assert rig.only_ever(TILT, START[TILT], since)
    rig.emu.delay(tilt, 0.0)
    rig.emu.set_angle(TILT, -0.5)
    assert until(lambda: rig.reads(TILT, -0.5))


def test_unplug_and_replug(rig: Rig) -> None:
    rig.emu.unplug()
    assert until(lambda: rig.bus.status()["state"] == "reconnecting")
    assert until(lambda: rig.bus.status()["stale"] == [PAN, TILT])
    assert "No such file" in (rig.bus.status()["problem"] or "") or until(
        lambda: "No such file" in (rig.bus.status()["problem"] or "")
    )
    rig.emu.set_angle(PAN, -0.25)
    rig.emu.set_angle(TILT, 0.35)
    rig.emu.replug()
    assert until(lambda: rig.reads(PAN, -0.25) and rig.reads(TILT, 0.35))
    status = rig.bus.status()
    assert status["reconnects"] == 1 and status["stale"] == [] and status["problem"] is None


def test_port_is_opened_exclusively() -> None:
    joints = JOINTS[2.0]
    with ServoEmulator(joints, 2.0) as emu:
        first = DynamixelBus(fast(2.0, emu.port_path), joints)
        second = DynamixelBus(fast(2.0, emu.port_path), joints)
        with first:
            assert until(lambda: first.latest() is not None)
            with second:
                assert until(lambda: "exclusively lock" in (second.status()["problem"] or ""))
                assert second.status()["state"] == "connecting" and second.latest() is None
                first.stop()
                assert until(lambda: second.status()["state"] == "connected")
                assert until(lambda: second.latest() is not None)


def test_failed_sync_read_yields_no_values() -> None:
    """The SDK's trap: after a failed sync read getData says 0 even for servos that answered."""
    joints = JOINTS[2.0]
    with ServoEmulator(joints, 2.0) as emu:
        emu.set_ticks(19, 3000)
        emu.mute(20)
        port, ph = sdk.PortHandler(emu.port_path), sdk.PacketHandler(2.0)
        assert port.openPort()
        try:
            group = sdk.GroupSyncRead(port, ph, 132, 4)
            group.addParam(19)
            group.addParam(20)
            assert group.txRxPacket() != sdk.COMM_SUCCESS
            assert group.getData(19, 132, 4) == 0  # servo 19 is at 3000 ticks
        finally:
            port.closePort()
        link = Link(emu.port_path, 1_000_000, 2.0, 0.02)
        try:
            with pytest.raises(ReadFailed):
                link.sync_read([19, 20], 132, 4)
            emu.mute(20, False)
            assert link.sync_read([19, 20], 132, 4) == {
                19: ((3000).to_bytes(4, "little"), 0),
                20: ((2048).to_bytes(4, "little"), 0),
            }
        finally:
            link.close()


def test_late_reply_to_another_read_is_refused() -> None:
    """A reply that arrives after its read timed out is not taken as the answer to the next."""
    joints = JOINTS[2.0]
    with ServoEmulator(joints, 2.0) as emu:
        link = Link(emu.port_path, 1_000_000, 2.0, 0.2)
        try:
            emu.delay(19, 0.3)
            with pytest.raises(ReadFailed, match="no status packet"):
                link.read(19, 132, 4)  # times out at 0.2 s; its reply comes at 0.3 s
            # The next read (1 byte) is still waiting when that 4-byte reply comes.
            with pytest.raises(ReadFailed, match="carries 4 bytes, asked for 1"):
                link.read(19, 70, 1)
        finally:
            link.close()


def test_emulator_answers_the_sdk_instruction_set_protocol2() -> None:
    joints = JOINTS[2.0]
    with ServoEmulator(joints, 2.0) as emu:
        emu.set_ticks(19, 1000)
        port, ph = sdk.PortHandler(emu.port_path), sdk.PacketHandler(2.0)
        assert port.openPort()
        try:
            found, result = ph.broadcastPing(port)
            assert result == sdk.COMM_SUCCESS and found == {19: [1020, 45], 20: [1020, 45]}
            assert ph.read4ByteTxRx(port, 19, 132) == (1000, sdk.COMM_SUCCESS, 0)
            assert ph.write1ByteTxRx(port, 19, 65, 1) == (sdk.COMM_SUCCESS, 0)
            assert emu.register(19, "led") == 1
            # Present position is read-only: access error (7), nothing written.
            assert ph.write4ByteTxRx(port, 19, 132, 5) == (sdk.COMM_SUCCESS, 7)
            # An error reply carries no data; the SDK hands out its CRC bytes as data instead
            # (and read4ByteTxRx raises IndexError). The driver's Link refuses it, see below.
            data, result, error = ph.readTxRx(port, 19, 400, 4)
            assert (result, error) == (sdk.COMM_SUCCESS, 7) and len(data) == 2
            bulk = sdk.GroupBulkRead(port, ph)
            assert bulk.addParam(19, 132, 4) and bulk.addParam(20, 146, 1)
            assert bulk.txRxPacket() == sdk.COMM_SUCCESS
            assert bulk.getData(19, 132, 4) == 1000 and bulk.getData(20, 146, 1) == 30
            sync = sdk.GroupSyncRead(port, ph, 132, 4)
            assert sync.addParam(19) and sync.addParam(20)
            assert sync.txRxPacket() == sdk.COMM_SUCCESS
            assert (sync.getData(19, 132, 4), sync.getData(20, 132, 4)) == (1000, 2048)
            # A hardware error sets the alert bit of every status packet; REBOOT clears it.
            emu.set_hardware_error(20, 0x20)
            assert ph.read1ByteTxRx(port, 20, 70) == (0x20, sdk.COMM_SUCCESS, 0x80)
            assert ph.reboot(port, 20) == (sdk.COMM_SUCCESS, 0x80)
            assert ph.read1ByteTxRx(port, 20, 70) == (0, sdk.COMM_SUCCESS, 0)
            # Instructions it does not know: instruction error (2), and no factory reset.
            assert ph.factoryReset(port, 19, 0xFF) == (sdk.COMM_SUCCESS, 2)
            # With torque on, a goal position is reached (at the model's top speed here).
            assert ph.write1ByteTxRx(port, 19, 64, 1) == (sdk.COMM_SUCCESS, 0)
            assert ph.write4ByteTxRx(port, 19, 116, 3000) == (sdk.COMM_SUCCESS, 0)
            assert until(lambda: emu.register(19, "present_position") == 3000)
        finally:
            port.closePort()
        link = Link(emu.port_path, 1_000_000, 2.0, 0.05)
        try:
            with pytest.raises(ReadFailed, match="carries 0 bytes, asked for 4"):
                link.read(19, 400, 4)
        finally:
            link.close()
    received = emu.received
    assert received["BULK_READ"] == 1 and received["SYNC_READ"] == 1 and received["REBOOT"] == 1


def test_emulator_answers_the_sdk_instruction_set_protocol1() -> None:
    joints = JOINTS[1.0]
    with ServoEmulator(joints, 1.0) as emu:
        emu.set_ticks(3, 700)
        port, ph = sdk.PortHandler(emu.port_path), sdk.PacketHandler(1.0)
        assert port.openPort()
        try:
            assert ph.ping(port, 3) == (12, sdk.COMM_SUCCESS, 0)  # AX-12A
            assert ph.ping(port, 4) == (29, sdk.COMM_SUCCESS, 0)  # MX-28
            assert ph.read2ByteTxRx(port, 3, 36) == (700, sdk.COMM_SUCCESS, 0)
            assert ph.write1ByteTxRx(port, 4, 25, 1) == (sdk.COMM_SUCCESS, 0)
            assert emu.register(4, "led") == 1
            assert ph.write2ByteTxRx(port, 4, 36, 5) == (sdk.COMM_SUCCESS, 0x08)  # range error
            # GroupBulkRead of SDK 4.1.0 breaks on 1.0 (bulkReadTx arity); its handler works.
            assert ph.bulkReadTx(port, [2, 3, 36, 1, 4, 43], 6) == sdk.COMM_SUCCESS
            assert ph.readRx(port, 3, 2) == ([700 & 0xFF, 700 >> 8], sdk.COMM_SUCCESS, 0)
            assert ph.readRx(port, 4, 1) == ([30], sdk.COMM_SUCCESS, 0)
            emu.set_hardware_error(4, 0x04)
            assert ph.read2ByteTxRx(port, 4, 36) == (2048, sdk.COMM_SUCCESS, 0x04)
            # No REBOOT or SYNC READ in 1.0 (the SDK does not even send them); others: bit 6.
            assert ph.factoryReset(port, 3) == (sdk.COMM_SUCCESS, 0x40)
        finally:
            port.closePort()


# -- the commands, as separate processes ---------------------------------------------------

AX_PROFILE = """
name = "ax-test"
[bus]
port = "/dev/null"
protocol = 1.0
[[joints]]
name = "head_pan"
id = 3
model = "AX-12A"
ticks_per_rev = 1228.8
zero_tick = 512
sign = -1
[[joints]]
name = "head_tilt"
id = 4
model = "MX-28"
[kinematics]
root_link = "base"
camera_link = "camera"
[[kinematics.joints]]
name = "head_pan"
parent = "base"
child = "pan"
[[kinematics.joints]]
name = "head_tilt"
parent = "pan"
child = "tilt"
axis = [0.0, 1.0, 0.0]
[[kinematics.joints]]
name = "camera_mount"
parent = "tilt"
child = "camera"
type = "fixed"
"""


def percept(*args: str) -> list[str]:
    script = Path(sys.executable).with_name("percept")
    head = [str(script)] if script.exists() else [sys.executable, "-m", "percept.runtime.cli"]
    return [*head, *args]


@dataclass
class Emulation:
    process: subprocess.Popen[str]
    port: str


def start_emulation(profile: Path, angles: dict[str, float]) -> Emulation:
    sets = [f"--set={name}={value}" for name, value in angles.items()]
    proc = subprocess.Popen(
        percept("emulate-servos", "--robot", str(profile), *sets),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        encoding="utf-8",
        cwd=ROOT,
    )
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], 30)
    assert ready, "emulate-servos printed no port path"
    return Emulation(proc, proc.stdout.readline().strip())


def end_emulation(emulation: Emulation, sig: signal.Signals) -> int:
    emulation.process.send_signal(sig)
    code = emulation.process.wait(timeout=10)
    emulation.process.stdout.close()  # type: ignore[union-attr]
    emulation.process.stderr.close()  # type: ignore[union-attr]
    return code


def sdk_reads(port_path: str, protocol: float, servo: JointSettings) -> tuple[int, int]:
    """(model number, present position) through the official SDK with its stock port handler."""
    port, ph = sdk.PortHandler(port_path), sdk.PacketHandler(protocol)
    assert port.openPort() and port.setBaudRate(1_000_000)
    try:
        for _ in range(20):  # the stock 34 ms timeout is short on a loaded machine
            model, result, error = ph.ping(port, servo.id)
            if result == sdk.COMM_SUCCESS:
                break
        assert (result, error) == (sdk.COMM_SUCCESS, 0), ph.getTxRxResult(result)
        for _ in range(20):
            if protocol == 2.0:
                ticks, result, error = ph.read4ByteTxRx(port, servo.id, 132)
            else:
                ticks, result, error = ph.read2ByteTxRx(port, servo.id, 36)
            if result == sdk.COMM_SUCCESS:
                break
        assert (result, error) == (sdk.COMM_SUCCESS, 0), ph.getTxRxResult(result)
        return model, ticks
    finally:
        port.closePort()


@pytest.mark.parametrize(
    ("profile", "sig"),
    [
        ("config/robots/robotis-op3.toml", signal.SIGTERM),
        ("config/robots/myon.toml", signal.SIGINT),
        ("ax-test", signal.SIGTERM),
    ],
)
def test_official_sdk_and_percept_joints_read_the_emulated_robot(
    profile: str, sig: signal.Signals, tmp_path: Path
) -> None:
    if profile == "ax-test":
        path = tmp_path / "ax-test.toml"
        path.write_text(AX_PROFILE, encoding="utf-8")
    else:
        path = ROOT / profile
    robot = load_profile(path)
    angles = {j.name: round(0.37 * (k + 1) * (-1) ** k, 3) for k, j in enumerate(robot.joints)}
    emulation = start_emulation(path, angles)
    try:
        assert os.path.exists(emulation.port)
        for joint in robot.joints:
            model, ticks = sdk_reads(emulation.port, robot.bus.protocol, joint)
            assert model == find_model(joint.model, robot.bus.protocol).number
            assert ticks == radians_to_ticks(angles[joint.name], joint)
        done = subprocess.run(
            percept("joints", "--robot", str(path), "--port", emulation.port, "--once", "--json"),
            capture_output=True,
            encoding="utf-8",
            timeout=30,
            cwd=ROOT,
        )
        assert done.returncode == 0, done.stderr
        lines = done.stdout.splitlines()
        assert len(lines) == 1
        reading = json.loads(lines[0])
        assert set(reading) == {"t", "joints", "stale"} and reading["stale"] == []
        for joint in robot.joints:
            tick = 2 * math.pi / joint.ticks_per_rev
            assert abs(reading["joints"][joint.name] - angles[joint.name]) <= tick
    finally:
        assert end_emulation(emulation, sig) == 0


def test_percept_joints_once_fails_clearly_when_no_servo_answers() -> None:
    profile = ROOT / "config/robots/robotis-op3.toml"
    robot = load_profile(profile)
    with ServoEmulator(robot.joints, 2.0) as emu:
        for joint in robot.joints:
            emu.mute(joint.id)
        done = subprocess.run(
            percept(
                "joints", "--robot", str(profile), "--port", emu.port_path, "--once", "--wait", "1"
            ),
            capture_output=True,
            encoding="utf-8",
            timeout=30,
        )
    assert done.returncode == 1 and done.stdout == ""
    assert "no reading from" in done.stderr and "within 1.0 s" in done.stderr
    missing = subprocess.run(
        percept(
            "joints",
            "--robot",
            str(profile),
            "--port",
            "/nonexistent/tty",
            "--once",
            "--wait",
            "0.5",
        ),
        capture_output=True,
        encoding="utf-8",
        timeout=30,
    )
    assert missing.returncode == 1
    assert "cannot open /nonexistent/tty" in missing.stderr


def test_servo_commands_refuse_bad_profiles_and_options(tmp_path: Path) -> None:
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(AX_PROFILE.replace("protocol = 1.0", "protocol = 2.0"), encoding="utf-8")
    done = subprocess.run(
        percept("joints", "--robot", str(wrong), "--once"), capture_output=True, encoding="utf-8"
    )
    assert done.returncode == 2
    assert f"{wrong}: joints[0].model: servo model 'AX-12A' speaks Protocol 1.0" in done.stderr
    op3 = str(ROOT / "config/robots/robotis-op3.toml")
    done = subprocess.run(
        percept("emulate-servos", "--robot", op3, "--set", "neck=0.1"),
        capture_output=True,
        encoding="utf-8",
    )
    assert done.returncode == 2 and "unknown joint 'neck'" in done.stderr and done.stdout == ""


def test_a_silent_emulated_servo_is_worded_as_the_emulators(
    caplog: pytest.LogCaptureFixture,
) -> None:
    joints = JOINTS[1.0]  # protocol 1.0 reads servo by servo: a silent one is named
    emu = ServoEmulator(joints, 1.0).start()
    bus = DynamixelBus(fast(1.0, emu.port_path), joints, logger="test.emulated", emulated=True)
    bus.start()
    try:
        emu.mute(joints[1].id)
        assert until(lambda: TILT in bus.status()["not_answering"])
        assert until(lambda: TILT in bus.status()["stale"])
        problem = bus.status()["not_answering"][TILT]
        assert problem.startswith("the servo emulator replied late, a busy machine: ")
        said = [r.getMessage() for r in caplog.records if r.name == "test.emulated"]
        assert any("servo emulator replied late" in m for m in said), said
        stale = [m for m in said if m.startswith("stale: ")]
        assert stale and all(
            m.endswith("(the servo emulator replies late, a busy machine)") for m in stale
        )
        assert not any("does not answer" in m for m in said), said
    finally:
        bus.stop()
        emu.stop()
