"""A new user's first hour (issue 14, items 11-13): what the README promises holds, and what fails
says so on the terminal."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.runtime.cli import main
from percept.runtime.settings.profile import load_profile
from tests.support.daemon import (
    ROOT,
    endpoint,
    experiment_copy,
    read_until,
    start_daemon,
    stop,
)

OP3 = ROOT / "config" / "robots" / "robotis-op3.toml"
ENV = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))


def _profile_with_folder(tmp_path: Path, frames: int) -> Path:
    """A copy of the OP3 profile in ``tmp_path/robot`` whose camera reads ``frames`` images from
    the relative folder ``frames``; the servo port does not exist."""
    folder = tmp_path / "robot" / "frames"
    folder.mkdir(parents=True)
    for i in range(frames):
        cv2.imwrite(str(folder / f"{i:04d}.png"), np.full((200, 320, 3), 90, np.uint8))
    text = OP3.read_text(encoding="utf-8").replace('source = "0"', 'source = "frames"', 1)
    text = text.replace('port = "', f'port = "{tmp_path}/no-such-port-', 1)
    path = tmp_path / "robot" / "robot.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_relative_camera_folder_is_relative_to_the_profile(tmp_path: Path) -> None:
    path = _profile_with_folder(tmp_path, 1)
    assert load_profile(path).camera.source == str(tmp_path / "robot" / "frames")
    original = path.read_text(encoding="utf-8")
    for kept in ("0", "sim", "/dev/video0", "v4l2src ! videoconvert ! appsink"):
        path.write_text(
            original.replace('source = "frames"', f'source = "{kept}"'), encoding="utf-8"
        )
        assert load_profile(path).camera.source == kept


@pytest.mark.timeout(60)
def test_a_daemon_that_gets_no_frames_says_so(tmp_path: Path) -> None:
    profile = _profile_with_folder(tmp_path, 3)  # fewer than the 30 calibration frames
    experiment = experiment_copy(tmp_path)
    cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
    cmd += ["--name", "a", "--robot", str(profile)]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=ENV, stderr=subprocess.PIPE)
    began = read_until(proc, "percept.devices: camera", 40.0)  # the daemon opened its devices
    time.sleep(1.0)
    code, _, err = stop(proc, signal.SIGINT)
    err = began + err
    assert code == 1, err[-2000:]
    assert f"ImageFolderCamera('{tmp_path / 'robot' / 'frames'}')" in err  # the profile's folder
    assert re.search(r"ERROR +percept.daemon: no frame processed in \d+ s", err), err[-2000:]
    assert "; no background model yet" in err  # 3 frames never make the 30 it calibrates on


def _hold(port_of: str) -> socket.socket:
    """A listening socket on the endpoint's port: the port is in use."""
    port = int(port_of.rsplit(":", 1)[1])
    sock = socket.socket()
    sock.bind(("127.0.0.1", port))
    sock.listen()
    return sock


@pytest.mark.timeout(60)
def test_port_in_use_exits_2_naming_the_endpoint(tmp_path: Path) -> None:
    experiment = experiment_copy(tmp_path)
    with _hold(endpoint(experiment, "a")):
        proc = start_daemon(experiment, "a")
        _, err = proc.communicate(timeout=40)
    text = err.decode()
    assert proc.returncode == 2, text[-2000:]
    assert "Traceback" not in text
    assert f"percept: {experiment}: robots[0].endpoint: a: cannot open a Zenoh session" in text
    assert "Address already in use" in text and ".cargo" not in text


def _demo(tmp_path: Path, *extra: str, seconds: int = 15) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "percept.runtime.cli", "demo", "--seconds", str(seconds)]
    cmd += ["--out", str(tmp_path / "demo"), *extra]
    return subprocess.run(
        cmd, cwd=ROOT, env=ENV, capture_output=True, encoding="utf-8", timeout=150
    )


@pytest.mark.timeout(150)
def test_demo_says_what_failed_instead_of_a_table(tmp_path: Path) -> None:
    experiment = experiment_copy(tmp_path)
    # The calibration's frames do not fit: each daemon refuses to start (exit 2).
    with experiment.open("a", encoding="utf-8") as fh:
        fh.write("\n[perception.background]\ncalibration_memory = 1.0\n")
    done = _demo(tmp_path, "--experiment", str(experiment), seconds=20)
    assert done.returncode == 1
    assert "objects matched at end" not in done.stdout and "None" not in done.stdout
    assert re.search(r"demo failed: (a, b|a|b) stopped early", done.stdout), done.stdout
    assert re.search(r"robot [ab] ended with exit code 2: ", done.stderr), done.stderr[-2000:]
    assert "more than calibration_memory = 1 MiB" in done.stderr


@pytest.mark.timeout(240)
def test_demo_on_the_myon_scene_and_its_jpeg_replay(tmp_path: Path) -> None:
    experiment = experiment_copy(tmp_path)
    # 640x480: calibration takes longer than on the OP3 camera (up to 20 s on a loaded machine).
    done = _demo(tmp_path, "--scene", "tabletop-myon", "--experiment", str(experiment), seconds=40)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    # The first seconds say what the daemons are doing instead of 0.0 fps.
    assert re.search(r"a: background calibrating \d+/30 \(keep the scene empty\)", done.stdout)
    assert " 0.0 fps" not in done.stdout
    summary = json.loads((tmp_path / "demo" / "summary.json").read_text(encoding="utf-8"))
    for robot in ("a", "b"):
        assert summary["robots"][robot]["matched_end"] >= 3, summary["robots"][robot]
        log = (tmp_path / "demo" / f"{robot}.log").read_text(encoding="utf-8")
        # The emulated bus logs under its own name, and its stale joints say so.
        assert "percept.dynamixel:" not in log
        for fault in re.findall(r"fault: (joint \S+ stale.*)", log):
            assert fault.startswith(f"joint {fault.split()[1]} stale (servo emulator)"), fault
    recording = tmp_path / "demo" / "a.mcap"
    replay = subprocess.run(
        [
            sys.executable,
            "-m",
            "percept.runtime.cli",
            "replay",
            "--as-fast-as-possible",
            str(recording),
        ],
        cwd=ROOT,
        env=ENV,
        capture_output=True,
        encoding="utf-8",
        timeout=120,
    )
    assert replay.returncode == 0, replay.stderr[-2000:]
    report = json.loads(replay.stdout)
    assert report["images"] == "jpeg" and report["differing"] > 0
    assert "recorded as jpeg (lossy)" in report["note"] and "--raw-images" in report["note"]
    assert "percept replay: expected: the images were recorded as jpeg" in replay.stderr


def test_explain_lists_keys_inside_lists_of_tables(capsys) -> None:
    assert main(["config", "--explain", "robot"]) == 0
    keys = {line.split()[0] for line in capsys.readouterr().out.splitlines()}
    assert {"joints[].id", "joints[].zero_tick", "kinematics.joints[].xyz"} <= keys
    assert main(["config", "--explain", "experiment"]) == 0
    keys = {line.split()[0] for line in capsys.readouterr().out.splitlines()}
    assert {"robots[].endpoint", "landmarks.boxes[].size"} <= keys


def test_version(capsys) -> None:
    from importlib.metadata import version

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"percept {version('percept')}"
