"""``percept look`` as a separate process against the emulated servos: it refuses unless gaze
is enabled, looks where it is told, stops as the torque policy says on SIGTERM, and killed
outright leaves the head to the bus watchdog."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.runtime.settings.profile import load_profile
from tests.drivers.dynamixel.test_dynamixel import ROOT, end_emulation, percept, start_emulation
from tests.support.daemon import experiment_copy
from tests.support.polling import wait_for

pytestmark = pytest.mark.timeout(90)

OP3 = ROOT / "config" / "robots" / "robotis-op3.toml"
PAN = "head_pan"


@pytest.fixture
def emu() -> Iterator[ServoEmulator]:
    profile = load_profile(OP3)
    with ServoEmulator.for_profile(profile.joints, profile.bus.protocol) as emulator:
        yield emulator


def look(port: str, *args: str) -> list[str]:
    return percept("look", "--robot", str(OP3), "--port", port, *args)


def run_look(port: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(look(port, *args), capture_output=True, encoding="utf-8", timeout=60)


def test_look_refuses_to_move_unless_gaze_is_enabled(emu: ServoEmulator, tmp_path: Path) -> None:
    done = run_look(emu.port_path, "--at", "1", "0.5")
    assert done.returncode == 2 and done.stdout == ""
    assert "gaze is not enabled" in done.stderr and "--enable-gaze" in done.stderr
    shipped = run_look(emu.port_path, "--at", "1", "0.5", "--experiment", "tabletop")
    assert shipped.returncode == 2 and "gaze is not enabled in tabletop" in shipped.stderr
    assert not {"WRITE", "SYNC_WRITE"} & set(emu.received)
    assert emu.register(19, "torque_enable") == 0
    enabled = experiment_copy(tmp_path, ("enabled = false", "enabled = true"))
    done = run_look(emu.port_path, "--at", "1", "0.5", "--experiment", str(enabled), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["settled"] and report["error_deg"] < 0.5
    assert emu.received["SYNC_WRITE"] > 0


def test_look_on_emulate_servos_and_read_back_with_percept_joints() -> None:
    emulation = start_emulation(OP3, {PAN: 0.0, "head_tilt": 0.0})
    try:
        done = run_look(emulation.port, "--at", "1.2", "-0.6", "0.1", "--enable-gaze", "--json")
        assert done.returncode == 0, done.stderr
        report = json.loads(done.stdout)
        assert report["settled"] and report["error_deg"] < 0.5
        assert report["torque_at_stop"] == "hold"
        # "settled" is within 0.5 degrees; the servos go on to the goal at their profile
        # velocity, and hold it: read back until they are within a tick (a loaded machine
        # slows the emulated motion).
        deadline = time.monotonic() + 10.0
        while True:
            read = subprocess.run(
                percept(
                    "joints", "--robot", str(OP3), "--port", emulation.port, "--once", "--json"
                ),
                capture_output=True,
                encoding="utf-8",
                timeout=30,
            )
            assert read.returncode == 0, read.stderr
            angles = json.loads(read.stdout)["joints"]
            off = {j: abs(angles[j] - goal) for j, goal in report["goals"].items()}
            if max(off.values()) < 2 * math.pi / 4096 or time.monotonic() > deadline:
                break
        assert max(off.values()) < 2 * math.pi / 4096, off
        behind = run_look(emulation.port, "--at", "-1", "0", "--enable-gaze")
        assert behind.returncode == 1 and "outside the head's range" in behind.stderr
    finally:
        assert end_emulation(emulation, signal.SIGTERM) == 0


def start_slow_look(port: str, *extra: str) -> subprocess.Popen[str]:
    """A look far to the left at 0.3 rad/s: about four seconds of motion."""
    return subprocess.Popen(
        look(port, "--at", "0.5", "1.2", "--speed", "0.3", "--wait", "20", *extra),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        encoding="utf-8",
    )


def moving(emu: ServoEmulator) -> bool:
    return emu.angle(PAN) > 0.15


def still(emu: ServoEmulator, seconds: float = 0.3) -> tuple[bool, float]:
    """Whether the pan joint did not move for ``seconds``; where it is."""
    first = emu.angle(PAN)
    time.sleep(seconds)
    return emu.angle(PAN) == first, first


def test_the_watchdog_stops_the_head_when_look_is_killed(emu: ServoEmulator) -> None:
    proc = start_slow_look(emu.port_path, "--enable-gaze")  # default watchdog: 0.2 s
    try:
        assert wait_for(lambda: moving(emu), timeout=30), proc.stderr
        proc.send_signal(signal.SIGKILL)
        at_kill = emu.angle(PAN)
        proc.wait(timeout=10)
    finally:
        proc.kill()
        proc.communicate()
    assert wait_for(lambda: emu.register(19, "bus_watchdog") == 0xFF, timeout=5)
    stopped, where = still(emu, 0.3)
    # Within one watchdog period (0.2 s at 0.3 rad/s: 0.06 rad), plus the time to deliver the
    # kill and read the emulator; far from the goal (1.18 rad).
    assert stopped and where < 1.0
    assert where - at_kill < 0.3 * (0.2 + 0.1)
    assert emu.register(19, "torque_enable") == 1


@pytest.mark.parametrize("policy", ["hold", "release"])
def test_torque_policy_at_sigterm(emu: ServoEmulator, tmp_path: Path, policy: str) -> None:
    experiment = experiment_copy(
        tmp_path,
        ("enabled = false", "enabled = true"),
        ('torque_at_stop = "hold"', f'torque_at_stop = "{policy}"'),
    )
    proc = start_slow_look(emu.port_path, "--experiment", str(experiment), "--json")
    try:
        assert wait_for(lambda: moving(emu), timeout=30)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert proc.returncode == 1 and "stopped by a signal" in err
    assert not json.loads(out)["settled"]
    stopped, where = still(emu, 0.5)
    assert stopped and where < 1.0  # stopped where it was, not at the goal
    for servo in (19, 20):
        assert emu.register(servo, "torque_enable") == (policy == "hold")
        assert emu.register(servo, "bus_watchdog") == 0  # disarmed: it stopped cleanly


@pytest.mark.parametrize(
    ("option", "value", "words"),
    [
        ("--speed", "nan", "--speed: nan is not a speed"),
        ("--speed", "-1", "--speed: -1.0 is not a speed"),
        ("--speed", "inf", "--speed: inf is not a speed"),
        ("--wait", "nan", "--wait: nan is not a wait"),
        ("--at", "inf", "--at: 1.0 inf is not a point"),
    ],
)
def test_look_checks_its_numbers_before_torque_on(
    emu: ServoEmulator, option: str, value: str, words: str
) -> None:
    at = ["--at", "1", value] if option == "--at" else ["--at", "1", "0.5", option, value]
    done = run_look(emu.port_path, *at, "--enable-gaze")
    assert done.returncode == 2 and words in done.stderr, done.stderr
    assert "Traceback" not in done.stderr and done.stdout == ""
    assert not {"WRITE", "SYNC_WRITE"} & set(emu.received)
    assert emu.register(19, "torque_enable") == 0
