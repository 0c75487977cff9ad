"""The onboard daemon end to end: ``percept run --sim`` against the simulated world, its servos
read through the Dynamixel emulator by the real driver, world models on real Zenoh (127.0.0.1),
recording, replay, and stopping by signal."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENT = ROOT / "config" / "experiments" / "tabletop.toml"
SCENE = "tabletop-basic"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def experiment_copy(tmp: Path) -> Path:
    """The default experiment with free ports and absolute profile paths."""
    text = EXPERIMENT.read_text()
    for port in ("7447", "7448"):
        text = text.replace(f"tcp/127.0.0.1:{port}", f"tcp/127.0.0.1:{free_port()}")
    text = text.replace('"../', f'"{EXPERIMENT.parent.parent}/')
    path = tmp / "experiment.toml"
    path.write_text(text)
    return path


def endpoint(experiment: Path, robot: str) -> str:
    from runtime.experiment import load_experiment

    return load_experiment(experiment).robot(robot).endpoint


def start_daemon(experiment: Path, robot: str, *extra: str) -> subprocess.Popen[bytes]:
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    cmd = [sys.executable, "-m", "runtime.cli", "run", "--experiment", str(experiment)]
    cmd += ["--name", robot, "--sim", SCENE, *extra]
    return subprocess.Popen(cmd, cwd=ROOT, env=env, stderr=subprocess.PIPE)


class Listener:
    """A Zenoh client on a robot's endpoint collecting its world and status messages."""

    def __init__(self, ep: str, prefix: str = "percept") -> None:
        import zenoh

        from runtime.zenoh_config import config

        self.worlds: list[dict] = []
        self.statuses: list[dict] = []
        self._lock = threading.Lock()
        settings = {
            "mode": "client",
            "connect": {"endpoints": [ep], "timeout_ms": -1},
            "scouting": {"multicast": {"enabled": False}},
        }
        self.session = zenoh.open(config(settings))
        self.subs = [
            self.session.declare_subscriber(f"{prefix}/*/world", self._on(self.worlds)),
            self.session.declare_subscriber(f"{prefix}/*/status", self._on(self.statuses)),
        ]

    def _on(self, into: list[dict]):
        def callback(sample) -> None:
            with self._lock:
                into.append(json.loads(sample.payload.to_bytes()))

        return callback

    def wait(self, predicate, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                if predicate(self):
                    return True
            time.sleep(0.1)
        return False

    def close(self) -> None:
        self.session.close()


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


@pytest.fixture(scope="module")
def live_run(tmp_path_factory):
    """One daemon run of robot a, recorded with raw images, watched on Zenoh, then SIGTERM."""
    tmp = tmp_path_factory.mktemp("daemon")
    experiment = experiment_copy(tmp)
    record = tmp / "a.mcap"
    proc = start_daemon(experiment, "a", "--record", str(record), "--raw-images")
    listener = Listener(endpoint(experiment, "a"))
    try:
        got = listener.wait(
            lambda s: sum(1 for w in s.worlds if w["objects"]) >= 20 and s.statuses, 60
        )
        code, seconds, err = stop(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
        listener.close()
    return {
        "got": got,
        "worlds": listener.worlds,
        "statuses": listener.statuses,
        "code": code,
        "seconds": seconds,
        "stderr": err,
        "record": record,
    }


@pytest.mark.timeout(120)
def test_world_messages_carry_seven_features_per_anchor(live_run):
    assert live_run["got"], live_run["stderr"][-3000:]
    worlds = [w for w in live_run["worlds"] if w["objects"]]
    from runtime.messages import World, decode

    for world in worlds:
        assert isinstance(decode(json.dumps(world).encode(), World.SCHEMA), World)
        for obj in world["objects"]:
            assert set(obj["features"]) == {
                "x",
                "y",
                "width",
                "height",
                "luminance",
                "green_red",
                "yellow_blue",
            }
            assert set(obj["scaled"]) == set(obj["features"])
    on_ground = [o for w in worlds for o in w["objects"] if o["on_ground"]]
    assert on_ground, "no anchor had a ground position"
    assert all(0.0 < o["features"]["x"] < 5.0 for o in on_ground)
    status = live_run["statuses"][-1]
    assert status["robot"] == "a" and status["fps"] > 0
    assert status["servos"]["state"] == "connected"


@pytest.mark.timeout(120)
def test_sigterm_stops_cleanly_within_two_seconds(live_run):
    assert live_run["code"] == 0, live_run["stderr"][-3000:]
    assert live_run["seconds"] < 2.0
    assert "stopped in" in live_run["stderr"]


@pytest.mark.timeout(120)
def test_replay_reproduces_the_recorded_world_models(live_run):
    from runtime.recording import Recording, read_recording
    from runtime.replay import ReplayReport, replay

    recording = Recording(live_run["record"])
    kinds: dict[str, int] = {}
    for kind, _ in read_recording(live_run["record"], recording):
        kinds[kind] = kinds.get(kind, 0) + 1
    assert not recording.truncated
    assert kinds.get("frame", 0) >= 20 and kinds.get("world", 0) == kinds["frame"]
    report = ReplayReport()
    worlds = list(replay(live_run["record"], speed=None, report=report))
    assert report.frames == kinds["frame"] == len(worlds)
    assert report.differing == []
    assert report.matched == kinds["world"]


@pytest.mark.timeout(120)
def test_sigkill_leaves_a_readable_recording(tmp_path):
    from runtime.recording import Recording, read_recording

    experiment = experiment_copy(tmp_path)
    record = tmp_path / "killed.mcap"
    proc = start_daemon(experiment, "b", "--record", str(record))
    listener = Listener(endpoint(experiment, "b"))
    try:
        assert listener.wait(lambda s: len(s.worlds) >= 30, 60), "no world models"
        time.sleep(1.5)  # let at least one chunk be flushed after the first worlds
        code, _, _ = stop(proc, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            proc.kill()
        listener.close()
    assert code == -signal.SIGKILL
    recording = Recording(record)
    frames = worlds = 0
    for kind, item in read_recording(record, recording):
        if kind == "frame":
            frames += 1
            assert item.image.ndim == 3
        worlds += kind == "world"
    assert recording.truncated
    assert frames >= 10 and worlds >= 10
    assert recording.metadata["robot"] == "b"
