"""Watching a run and the frictions of a new user's first hour: the status line of ``percept
run`` on a real terminal (a pty), what ``percept monitor`` waits for, a recording replayed from
any folder, a reader that stops reading, ``track`` on a ``percept sim`` folder, names in
summaries, figures with numbered axes."""

from __future__ import annotations

import fcntl
import json
import logging
import os
import pty
import re
import select
import signal
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import numpy as np
import pytest

from percept.runtime.console import status_line
from percept.runtime.net.messages import Status
from percept.runtime.net.ports import free_port
from tests.support.daemon import ROOT, experiment_copy

ENV = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
CLI = [sys.executable, "-m", "percept.runtime.cli"]


def _on_pty(cmd: list[str], cwd: Path, until: str, timeout: float) -> tuple[int, str]:
    """Run ``cmd`` with stdin, stdout and stderr on a pty 160 columns wide, until its output
    matches ``until`` (or ``timeout`` s), then SIGINT; (exit code, everything it wrote)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))
    proc = subprocess.Popen(cmd, cwd=cwd, env=ENV, stdin=slave, stdout=slave, stderr=slave)
    os.close(slave)
    out = b""
    deadline = time.monotonic() + timeout
    stopping = False
    try:
        while True:
            if not stopping and (
                re.search(until, out.decode(errors="replace")) or time.monotonic() > deadline
            ):
                proc.send_signal(signal.SIGINT)
                stopping = True
                deadline = time.monotonic() + 30
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    chunk = os.read(master, 65536)
                except OSError:  # EIO: every writer closed the pty
                    break
                if not chunk:
                    break
                out += chunk
            elif stopping and (proc.poll() is not None or time.monotonic() > deadline):
                break
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
        proc.wait()
    return proc.returncode, out.decode(errors="replace")


def _status(**fields: object) -> Status:
    base: dict[str, object] = {
        "robot": "a",
        "stamp": 1.0,
        "fps": 14.5,
        "dropped_frames": 0,
        "camera": {},
        "servos": {},
        "peers": {},
        "rejected_messages": 0,
        "faults": (),
        "background": "calibrated",
    }
    return Status(**{**base, **fields})  # type: ignore[arg-type]


def test_the_status_line_says_calibration_then_rates_games_and_faults() -> None:
    assert status_line(None, None).startswith("starting")
    calibrating = _status(background="calibrating 12/30", faults=("no background model yet",))
    assert status_line(calibrating, None) == (
        "a | background calibrating 12/30 (keep the scene empty) | no faults"
    )
    games = {"played": 3, "success": 2, "guessing_played": 5, "guessing_success": 4}
    line = status_line(
        _status(games={**games, "lexicon_size": 6}, faults=("peer b not heard",)), None
    )
    assert line == (
        "a | 14.5 fps 0 anchors 0 boxes peer - | pointing 2/3 guessing 4/5 (6 words) | "
        "1 fault: peer b not heard"
    )


@pytest.mark.timeout(300)
def test_run_on_a_terminal_shows_its_status_and_its_recording_replays_from_anywhere(
    tmp_path: Path,
) -> None:
    # The shipped experiment by name, on ports and a key prefix of this test's own.
    recording = tmp_path / "a.mcap"
    cmd = [*CLI, "run", "--experiment", "tabletop", "--name", "a", "--sim", "tabletop-basic"]
    cmd += ["--prefix", f"test-{os.getpid()}", "--endpoint", f"a=tcp/127.0.0.1:{free_port()}"]
    cmd += ["--endpoint", f"b=tcp/127.0.0.1:{free_port()}", "--record", str(recording)]
    code, out = _on_pty(cmd, ROOT, r"a \| +[\d.]+ fps \d+ anchors", timeout=100)
    assert code == 130, out[-3000:]  # Ctrl-C after world models: see runtime.daemon.stopping
    lines = out.split("\r\x1b[K")
    assert any(re.match(r"a \| background calibrating \d+/\d+ \(keep", s) for s in lines), out
    shown = [s for s in lines if re.match(r"a \| +[\d.]+ fps \d+ anchors \d+ boxes peer ", s)]
    assert shown, out[-3000:]
    assert re.search(r"\| pointing \d+/\d+ guessing \d+/\d+ \(\d+ words\) \| ", shown[-1])
    assert re.search(r"\| (no faults|\d+ faults?: .+)$", shown[-1].splitlines()[0]), shown[-1]
    # The log goes above the line: a log record never starts in the middle of a status line.
    assert not re.search(r"(fps|faults?|words\))[^\n\r]*\d{4}-\d\d-\d\d \d\d:\d\d:\d\d", out)
    # A recording of the shipped experiment replays with no option, from another folder.
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    replay = subprocess.run(
        [*CLI, "replay", "--as-fast-as-possible", str(recording)],
        cwd=elsewhere,
        env=ENV,
        capture_output=True,
        encoding="utf-8",
        timeout=180,
    )
    assert replay.returncode == 0, replay.stderr[-2000:]
    assert json.loads(replay.stdout)["frames"] > 0


@pytest.mark.timeout(60)
def test_quiet_or_not_a_terminal_shows_no_status_line(tmp_path: Path) -> None:
    experiment = experiment_copy(tmp_path)
    cmd = [*CLI, "run", "--experiment", str(experiment), "--name", "a", "--sim", "tabletop-basic"]
    _, out = _on_pty([*cmd, "--quiet"], ROOT, "percept.daemon: ", timeout=40)
    assert "percept.daemon: " in out, out[-2000:]
    assert "\x1b[K" not in out and "no faults" not in out
    proc = subprocess.Popen(cmd, cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    time.sleep(3.0)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=30)
    assert b"\x1b[K" not in stdout + stderr and b" | starting" not in stderr


@pytest.mark.timeout(60)
def test_monitor_says_what_it_waits_for(tmp_path: Path) -> None:
    experiment = experiment_copy(tmp_path)
    done = subprocess.run(
        [*CLI, "monitor", "--experiment", str(experiment), "--seconds", "2.5"],
        cwd=tmp_path,
        env=ENV,
        capture_output=True,
        encoding="utf-8",
        timeout=50,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "percept monitor: watching robots a, b on keys percept/*" in done.stderr
    assert "percept monitor: waiting for the world models of a, b" in done.stderr
    assert done.stdout == ""  # events only


def test_a_recording_made_before_names_were_stored_replays(tmp_path: Path) -> None:
    from percept.runtime.record.reader import RecordingError
    from percept.runtime.record.replay import _recorded_file

    # What earlier recordings hold: the shipped name as a path in the folder the robot ran in.
    meta = {"experiment": str(tmp_path / "tabletop"), "profile": "robotis-op3"}
    assert _recorded_file("x.mcap", meta, "experiments", "--experiment") == "tabletop"
    assert _recorded_file("x.mcap", meta, "robots", "--robot") == "robotis-op3"
    gone = {"experiment": str(tmp_path / "mine.toml"), "profile": "robotis-op3"}
    with pytest.raises(RecordingError, match=r"x.mcap: recorded with the experiment .*mine.toml"):
        _recorded_file("x.mcap", gone, "experiments", "--experiment")


def test_a_closed_pipe_ends_quietly(tmp_path: Path) -> None:
    read, write = os.pipe()
    os.close(read)  # the reader is gone before the first line: like `| head -0`
    done = subprocess.run(
        [*CLI, "config", "--explain", "experiment"],
        stdout=write,
        stderr=subprocess.PIPE,
        env=ENV,
        encoding="utf-8",
        timeout=60,
    )
    os.close(write)
    assert "BrokenPipeError" not in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert done.returncode == 141


def test_port_given_on_the_command_line_in_use_names_the_option(tmp_path: Path) -> None:
    import socket

    experiment = experiment_copy(tmp_path)
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        endpoint = ["--name", "a", "--endpoint", f"a=tcp/127.0.0.1:{held.getsockname()[1]}"]
        done = subprocess.run(
            [*CLI, "run", "--experiment", str(experiment), "--sim", "tabletop-basic", *endpoint],
            cwd=ROOT,
            env=ENV,
            capture_output=True,
            encoding="utf-8",
            timeout=60,
        )
    assert done.returncode == 2, done.stderr[-2000:]
    assert "percept: --endpoint: a: " in done.stderr and "give another port there" in done.stderr


@pytest.mark.timeout(120)
def test_track_uses_the_joint_angles_of_a_sim_folder(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    from percept.runtime.cli import main
    from percept.runtime.commands import _sequence
    from percept.runtime.commands.offline import track

    folder = tmp_path / "pan"
    sim = [*CLI, "sim", "--scene", "tabletop-pan", "--robot", "a", "--seconds", "1.5"]
    subprocess.run([*sim, "--out", str(folder)], env=ENV, check=True, capture_output=True)
    with caplog.at_level(logging.INFO):
        out = ["--out", str(tmp_path / "t.txt"), "--calibration-frames", "10"]
        assert main(["track", str(folder), *out]) == 0
    assert "with the robot profile robotis-op3 that its seqinfo.ini names" in caplog.text
    caplog.clear()
    sequence = _sequence.open_sequence(folder)
    assert sequence.recorded_profile() == "robotis-op3"
    # An older folder names no profile: said, not silent.
    ini = folder / "seqinfo.ini"
    ini.write_text(ini.read_text().split("[percept]")[0])
    with caplog.at_level(logging.WARNING):
        assert track._profile_of(_sequence.open_sequence(folder)) is None
    assert "joints.csv holds the joint angles but seqinfo.ini names no robot profile" in caplog.text


def test_curves_and_scatter_have_numbered_axes() -> None:
    from percept.runtime.games.language.dataset.agreement import Agreement
    from percept.runtime.games.language.figures import MARGIN, PANEL, curves, scatter

    image = curves("success", [0, 1000, 2000], {"success": [0.0, 0.5, 0.9]}, top=1.0)
    width, height = 560, 200
    bar = 22  # the caption's
    below = image[bar + MARGIN + height + 6 : bar + MARGIN + height + 18]
    for k in range(5):  # a number under each fifth of the games axis
        u = MARGIN + round(width * k / 4)
        assert (below[:, max(0, u - 8) : u + 8] < 128).any(), k
    left = image[bar + MARGIN : bar + MARGIN + height, : MARGIN - 5]
    assert (left < 128).sum() > 50  # values along the left axis
    pairs = ((0.1, 0.2), (0.5, 0.45), (0.9, 0.95))
    panel = scatter("hue", Agreement(d=0.05, r=0.99, n=3, pairs=pairs))
    under = panel[bar + MARGIN + PANEL + 6 : bar + MARGIN + PANEL + 18]
    for tick in (0.0, 0.5, 1.0):
        u = MARGIN + round(tick * PANEL)
        assert (under[:, max(0, u - 8) : u + 8] < 128).any(), tick
    assert np.array_equal(panel.shape[:2], (bar + 2 * MARGIN + PANEL, 2 * MARGIN + PANEL))
