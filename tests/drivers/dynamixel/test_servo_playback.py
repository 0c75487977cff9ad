"""The servo emulator playing recorded joint angles back: the real dynamixel-sdk on the pty reads
the recording at its times, goals are taken but move nothing; the CLI's --play and --epoch."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import dynamixel_sdk as sdk
import numpy as np
import pytest

from percept.drivers.dynamixel.bus import radians_to_ticks
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.playback import RecordingError, read_recording
from percept.runtime.settings.profile import load_profile
from tests.drivers.dynamixel.test_dynamixel import (
    JOINTS,
    PAN,
    TILT,
    Emulation,
    end_emulation,
    percept,
    sdk_reads,
)

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[3]
PRESENT, GOAL, TORQUE = 132, 116, 64  # X series control table addresses

# As percept sim writes joints.csv: the pan ramps 0 -> 0.6 rad over 0.6 s and back, tilt holds.
RECORDING = "frame,t,head_pan,head_tilt\n" + "".join(
    f"{k + 1},{k / 10:.6f},{min(k, 12 - k) / 10:.6f},-0.200000\n" for k in range(13)
)


def test_the_sdk_reads_the_recorded_angles_at_their_times(tmp_path: Path) -> None:
    path = tmp_path / "joints.csv"
    path.write_text(RECORDING, encoding="utf-8")
    pan, tilt = JOINTS[2.0]
    recording = read_recording(path, [PAN, TILT, "neck"])
    assert set(recording.angles) == {PAN, TILT} and recording.duration == pytest.approx(1.2)
    with ServoEmulator(JOINTS[2.0], 2.0) as emu:
        epoch = time.time() + 0.3
        emu.play(recording, epoch)
        port, ph = sdk.PortHandler(emu.port_path), sdk.PacketHandler(2.0)
        assert port.openPort()
        try:
            # Torque on and a goal far away: taken, but the shaft follows the recording.
            assert ph.write1ByteTxRx(port, pan.id, TORQUE, 1) == (sdk.COMM_SUCCESS, 0)
            assert ph.write4ByteTxRx(port, pan.id, GOAL, 3500) == (sdk.COMM_SUCCESS, 0)
            reads = []
            while time.time() < epoch + 1.5:
                before = time.time()
                ticks, result, error = ph.read4ByteTxRx(port, pan.id, PRESENT)
                after = time.time()
                if (result, error) == (sdk.COMM_SUCCESS, 0):
                    reads.append((before - epoch, after - epoch, ticks))
                time.sleep(0.01)
            tilt_ticks, result, _ = ph.read4ByteTxRx(port, tilt.id, PRESENT)
        finally:
            port.closePort()
        assert emu.goals(pan.id) == [3500]
    assert result == sdk.COMM_SUCCESS and tilt_ticks == radians_to_ticks(-0.2, tilt)

    def expected(elapsed: float) -> float:
        return radians_to_ticks(recording.at(elapsed)[PAN], pan)

    assert len(reads) > 30
    for before, after, ticks in reads:
        # the servo was read somewhere between the two times: its value lies between theirs
        lo, hi = sorted((expected(before), expected(after)))
        if before < 0.6 < after:  # the ramp's top in between
            hi = expected(0.6)
        assert lo - 1 <= ticks <= hi + 1, (before, after, ticks)
    seen = {ticks for _, _, ticks in reads}
    top = radians_to_ticks(0.6, pan)
    assert radians_to_ticks(0.0, pan) in seen  # before the epoch and after the end
    assert max(seen) > top - 80  # near the top of the ramp (60 ticks a 10 ms step)
    assert len(seen) > 10  # it moved through the recording, not jumping between rows' ends


def test_bad_recordings_are_refused_with_the_file_and_problem(tmp_path: Path) -> None:
    bad = {
        "empty.csv": "",
        "nojoint.csv": "frame,t,neck\n1,0.0,0.1\n",
        "nan.csv": "t,head_pan\n0.0,0.1\n0.1,x\n",
        "back.csv": "t,head_pan\n0.1,0.1\n0.0,0.1\n",
    }
    problems = {
        "empty.csv": "no rows",
        "nojoint.csv": "expected a t column and at least one joint column of head_pan",
        "nan.csv": "not a number",
        "back.csv": "must increase",
    }
    for name, text in bad.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
        with pytest.raises(RecordingError, match=problems[name]) as err:
            read_recording(tmp_path / name, [PAN])
        assert str(tmp_path / name) in str(err.value)


def test_emulate_servos_play_from_an_epoch(tmp_path: Path) -> None:
    path = tmp_path / "joints.csv"
    path.write_text(RECORDING, encoding="utf-8")
    profile = ROOT / "config/robots/myon.toml"
    robot = load_profile(profile)
    joint = next(j for j in robot.joints if j.name == PAN)
    done = subprocess.run(
        percept("emulate-servos", "--robot", str(profile), "--epoch", "1"),
        capture_output=True,
        encoding="utf-8",
        timeout=30,
        cwd=ROOT,
    )
    assert done.returncode == 2 and "--epoch needs --play" in done.stderr
    missing = percept("emulate-servos", "--robot", str(profile), "--play", str(tmp_path / "no"))
    done = subprocess.run(missing, capture_output=True, encoding="utf-8", timeout=30, cwd=ROOT)
    assert done.returncode == 2 and "cannot read" in done.stderr
    # The recording's first row 100 s ago: its last row holds.
    command = ["--robot", str(profile), "--play", str(path), "--epoch", repr(time.time() - 100)]
    proc = subprocess.Popen(
        percept("emulate-servos", *command),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        encoding="utf-8",
        cwd=ROOT,
    )
    assert proc.stdout is not None
    emulation = Emulation(proc, proc.stdout.readline().strip())
    try:
        _, ticks = sdk_reads(emulation.port, robot.bus.protocol, joint)
        assert ticks == radians_to_ticks(0.0, joint)
        tilt = next(j for j in robot.joints if j.name == TILT)
        _, ticks = sdk_reads(emulation.port, robot.bus.protocol, tilt)
        assert np.isclose(ticks, radians_to_ticks(-0.2, tilt), atol=1)
    finally:
        assert end_emulation(emulation, signal.SIGTERM) == 0
