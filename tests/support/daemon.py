"""Daemons for tests: the shipped experiment made ready (free ports, absolute profile paths),
`percept run --sim` started and stopped by signal."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path

from tests.support.zenoh_rig import free_port

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENT = ROOT / "config" / "experiments" / "tabletop.toml"


def experiment_copy(tmp: Path, *edits: tuple[str, str]) -> Path:
    """The default experiment with free ports and absolute profile paths, and each ``(old,
    new)`` of ``edits`` replaced (``old`` must be there)."""
    text = EXPERIMENT.read_text(encoding="utf-8")
    for old, new in edits:
        if old not in text:
            raise ValueError(f"{old!r} is not in {EXPERIMENT}")
        text = text.replace(old, new)
    for port in ("7447", "7448"):
        text = text.replace(f"tcp/127.0.0.1:{port}", f"tcp/127.0.0.1:{free_port()}")
    text = text.replace('"../', f'"{EXPERIMENT.parent.parent}/')
    path = tmp / "experiment.toml"
    path.write_text(text, encoding="utf-8")
    return path


def endpoint(experiment: Path, robot: str) -> str:
    from percept.runtime.settings.experiment import load_experiment

    return load_experiment(experiment).robot(robot).endpoint


SCENE = "tabletop-basic"


def start_daemon(
    experiment: Path, robot: str, *extra: str, env: Mapping[str, str] | None = None
) -> subprocess.Popen[bytes]:
    """``percept run --sim`` as ``robot``; ``env``: more environment variables."""
    gl = os.environ.get("MUJOCO_GL", "egl")
    env = {**os.environ, "MUJOCO_GL": gl, **(env or {})}
    cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
    cmd += ["--name", robot, "--sim", SCENE, *extra]
    return subprocess.Popen(cmd, cwd=ROOT, env=env, stderr=subprocess.PIPE)


def stop(proc: subprocess.Popen[bytes], sig: int = signal.SIGTERM) -> tuple[int, float, str]:
    """Send ``sig``; (exit code, seconds to exit, stderr)."""
    began = time.monotonic()
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return proc.returncode, time.monotonic() - began, err.decode(errors="replace")


def read_until(proc: subprocess.Popen[bytes], words: str, timeout: float) -> str:
    """``proc``'s stderr up to the first line holding ``words`` (all of it if it ends first):
    a stop that must find the daemon started waits for its line, not a guessed time."""
    assert proc.stderr is not None
    deadline, lines = time.monotonic() + timeout, []
    while time.monotonic() < deadline:
        line = proc.stderr.readline().decode(errors="replace")
        lines.append(line)
        if not line or words in line:
            break
    return "".join(lines)
