"""Faults across the running daemon: for each, the daemon stays up, names the fault in its
status and its log within a second, recovers by itself within five seconds of the fault's end,
and keeps every recorded message written before it; bad configuration ends it with exit code 2
and a message naming the file and the key.

The daemon (robot a, simulated world, emulated servos read by the real driver, real Zenoh on
127.0.0.1) runs in this process with short timings (see :mod:`tests.fault_rig`, which
``bench/faults.py`` shares); the full disk and the exit codes use ``percept run`` processes.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.support.fault_rig import (
    EXPERIMENT,
    PROFILE,
    ROOT,
    SCENARIOS,
    SCENE,
    Measurement,
    ProcessRig,
    Rig,
    disk_full,
)

os.environ.setdefault("MUJOCO_GL", "egl")

REPORT_WITHIN = 1.0  # seconds from a fault to the status and the log naming it
RECOVER_WITHIN = 5.0  # seconds from a fault's end to a status without faults

MEASURED: list[Measurement] = []


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory):
    rig = Rig(tmp_path_factory.mktemp("faults"))
    try:
        yield rig.start()
    finally:
        rig.close()


def _check(m: Measurement, alive: bool, error: object) -> None:
    assert alive, f"the daemon did not stay up: {error}"
    assert m.reported is not None, f"{m.fault}: not reported"
    assert m.reported <= REPORT_WITHIN, f"{m.fault}: reported after {m.reported:.2f} s"
    assert m.logged is not None and m.logged <= REPORT_WITHIN, f"{m.fault}: logged {m.logged}"
    assert m.recovered is not None, f"{m.fault}: no recovery"
    assert m.recovered <= RECOVER_WITHIN, f"{m.fault}: recovered after {m.recovered:.2f} s"


@pytest.mark.timeout(120)
@pytest.mark.parametrize("scenario", SCENARIOS, ids=[s.name for s in SCENARIOS])
def test_fault_is_reported_and_recovered(rig: Rig, scenario) -> None:
    threads = threading.active_count()
    m = rig.measure(
        scenario.name, scenario.expect, lambda: scenario.inject(rig), lambda: scenario.end(rig)
    )
    MEASURED.append(m)
    print(f"{m.fault}: reported {m.reported}, logged {m.logged}, recovered {m.recovered}")
    _check(m, rig.alive(), rig.daemon.error)
    assert scenario.shows(m.status), json.dumps(m.status)[:2000]
    # e.g. a flood of start signals must not leave a thread per game behind
    assert threading.active_count() <= threads + 2


@pytest.mark.timeout(120)
def test_recording_keeps_every_message_written_before_each_fault(rig: Rig) -> None:
    from percept.runtime.record.recording import Recording, read_recording

    stopping = rig.stop()
    sent = rig.watch.world_stamps(before=stopping - 0.5)
    recording = Recording(rig.record)
    recorded = {w["stamp"] for kind, w in read_recording(rig.record, recording) if kind == "world"}
    assert not recording.truncated
    assert len(sent) >= 30
    missing = sorted(sent - recorded)
    assert not missing, f"{len(missing)} world models sent on Zenoh are not in the recording"
    for m in MEASURED:  # the second before each fault is there
        before = [s for s in recorded if m.began_wall - 1.0 <= s < m.began_wall]
        assert before, f"nothing recorded in the second before {m.fault}"


@pytest.mark.timeout(120)
def test_full_disk_is_reported_survived_and_recording_goes_on(tmp_path: Path) -> None:
    from percept.runtime.record.recording import Recording, read_recording

    rig = ProcessRig(tmp_path).start()
    try:
        deadline = time.monotonic() + 30.0  # something to lose
        while len(rig.watch.worlds) < 60 and time.monotonic() < deadline:
            time.sleep(0.05)
        m = disk_full(rig)
        alive = rig.alive()
        time.sleep(1.5)  # recorded in the continuation file
        stopping = time.monotonic()
        code = rig.stop()
    finally:
        rig.close()
    _check(m, alive, "exit code " + str(rig.proc.returncode if rig.proc else None))
    assert code == 0
    state = m.status["recording"]
    assert state["state"] == "failed" and state["error"] == "File too large", state
    flushed = state["flushed"]
    assert flushed >= m.began_wall - 1.0  # at most a flush interval (0.5 s) is lost
    first, cont = Recording(rig.record), Recording(tmp_path / "a.1.mcap")
    kept = {w["stamp"] for kind, w in read_recording(rig.record, first) if kind == "world"}
    went_on = {w["stamp"] for kind, w in read_recording(cont.path, cont) if kind == "world"}
    assert first.truncated and not cont.truncated
    assert cont.metadata["robot"] == "a" and "background.npz" in cont.attachments
    sent = rig.watch.world_stamps(before=stopping - 0.5)
    on_disk = {s for s in sent if s < flushed - 0.5}  # logged before the last good flush
    assert on_disk and on_disk <= kept
    resumed = m.ended_wall + (m.recovered or 0.0) + 0.5
    later = {s for s in sent if s > resumed}
    assert later and later <= went_on


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _experiment(tmp: Path, profile: Path = PROFILE) -> str:
    text = EXPERIMENT.read_text().replace('"../robots/robotis-op3.toml"', json.dumps(str(profile)))
    return text.replace('"../', f'"{EXPERIMENT.parent.parent}/')


def _case(name: str, tmp: Path) -> tuple[Path, Path, str]:
    """(experiment to run, file the message must name, key it must name)."""
    good = _experiment(tmp)
    exp = tmp / "experiment.toml"
    if name == "missing key":
        return _write(exp, good.replace('name = "tabletop"\n', "", 1)), exp, "name"
    if name == "wrong type":
        bad = good.replace("world_rate = 0.0", 'world_rate = "fast"')
        return _write(exp, bad), exp, "daemon.world_rate"
    if name == "unknown key":
        bad = good.replace("world_rate = 0.0", "world_rate = 0.0\ncolour = 1")
        return _write(exp, bad), exp, "daemon.colour"
    if name == "unknown joint name":
        profile = _write(
            tmp / "robot.toml",
            PROFILE.read_text().replace('name = "head_pan"', 'name = "head_yaw"', 1),
        )
        return _write(exp, _experiment(tmp, profile)), profile, "joints[0].name"
    if name == "wrong type in the profile":
        profile = _write(
            tmp / "robot.toml", PROFILE.read_text().replace("rate = 100.0", 'rate = "x"')
        )
        return _write(exp, _experiment(tmp, profile)), profile, "bus.rate"
    if name == "missing profile file":
        return _write(exp, _experiment(tmp, tmp / "nowhere.toml")), exp, "robots[0].profile"
    if name == "missing scaling file":
        bad = good.replace("scaling/tabletop.toml", "scaling/nowhere.toml")
        return _write(exp, bad), exp, "scaling"
    if name == "missing experiment file":
        return tmp / "nowhere.toml", tmp / "nowhere.toml", "file not found"
    raise AssertionError(name)


CASES = [
    "missing key",
    "wrong type",
    "unknown key",
    "unknown joint name",
    "wrong type in the profile",
    "missing profile file",
    "missing scaling file",
    "missing experiment file",
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("name", CASES)
def test_bad_config_ends_with_code_2_naming_file_and_key(name: str, tmp_path: Path, capsys) -> None:
    from percept.runtime.cli import main

    experiment, file, key = _case(name, tmp_path)
    code = main(["run", "--experiment", str(experiment), "--name", "a", "--sim", SCENE])
    err = capsys.readouterr().err
    assert code == 2
    assert f"percept: {file}: {key}" in err, err


@pytest.mark.timeout(60)
def test_bad_config_exit_code_of_the_process(tmp_path: Path) -> None:
    experiment, file, key = _case("unknown key", tmp_path)
    cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
    cmd += ["--name", "a", "--sim", SCENE]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert f"percept: {file}: {key}: unknown key" in proc.stderr
