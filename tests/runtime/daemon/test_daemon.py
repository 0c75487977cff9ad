"""The onboard daemon end to end: ``percept run --sim`` against the simulated world, its servos
read through the Dynamixel emulator by the real driver, world models on real Zenoh (127.0.0.1),
recording, replay, and stopping by signal."""

from __future__ import annotations

import json
import signal
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from tests.support.daemon import ROOT, endpoint, experiment_copy, start_daemon, stop
from tests.support.zenoh_rig import free_port


class Listener:
    """A Zenoh client on a robot's endpoint collecting that robot's world and status messages
    (the robot's peers route the others' to it too)."""

    def __init__(self, ep: str, robot: str, prefix: str = "percept") -> None:
        import zenoh

        from percept.runtime.net.zenoh_config import client_config

        self.robot = robot

        self.worlds: list[dict] = []
        self.statuses: list[dict] = []
        self._lock = threading.Lock()
        self.session = zenoh.open(client_config([ep], connect_timeout=None))
        self.subs = [
            self.session.declare_subscriber(f"{prefix}/*/world", self._on(self.worlds)),
            self.session.declare_subscriber(f"{prefix}/*/status", self._on(self.statuses)),
        ]

    def _on(self, into: list[dict]):
        def callback(sample) -> None:
            message = json.loads(sample.payload.to_bytes())
            if message["robot"] == self.robot:
                with self._lock:
                    into.append(message)

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


def variant(experiment: Path, name: str, table: str) -> Path:
    """A copy of ``experiment`` (same robots and endpoints) with ``table`` (TOML) in place of
    the table of the same name."""
    header = table.splitlines()[0]
    text = experiment.read_text(encoding="utf-8")
    start = text.find(header)
    if start < 0:
        text += "\n" + table.strip() + "\n"
    else:
        end = text.find("\n[", start + len(header))
        text = text[:start] + table.strip() + "\n" + ("" if end < 0 else text[end:])
    path = experiment.with_name(name)
    path.write_text(text, encoding="utf-8")
    return path


def peer_gone(status: dict, peer: str) -> bool:
    """Whether ``status`` says ``peer`` is gone (liveliness: not heard, no age at all)."""
    entry = status["peers"].get(peer)
    return entry is not None and not entry["heard"] and entry["age"] is None


@pytest.fixture(scope="module")
def live_run(tmp_path_factory):
    """Robot a (servos through the emulator, recorded with raw images, watched on Zenoh) and
    robot b (joints read directly from the simulation) until a locates b; then b stops and a
    must notice at once; then a stops by SIGTERM."""
    tmp = tmp_path_factory.mktemp("daemon")
    experiment = experiment_copy(tmp)
    direct = variant(experiment, "direct.toml", '[sim]\njoints = "direct"')
    record = tmp / "a.mcap"
    proc = start_daemon(experiment, "a", "--record", str(record), "--raw-images")
    peer = start_daemon(direct, "b")
    listener = Listener(endpoint(experiment, "a"), "a")
    gone = False
    try:
        got = listener.wait(
            lambda s: (
                sum(1 for w in s.worlds if w["objects"]) >= 20
                and any("b" in w["peers"] for w in s.worlds)
                and s.statuses
            ),
            90,
        )
        peer_code, _, peer_err = stop(peer)
        gone = listener.wait(lambda s: peer_gone(s.statuses[-1], "b"), 10)
        code, seconds, err = stop(proc)
    finally:
        for p in (proc, peer):
            if p.poll() is None:
                p.kill()
        listener.close()
    return {
        "got": got,
        "gone": gone,
        "worlds": listener.worlds,
        "statuses": listener.statuses,
        "code": code,
        "seconds": seconds,
        "stderr": err,
        "peer_code": peer_code,
        "peer_stderr": peer_err,
        "record": record,
        "experiment": experiment,
    }


@pytest.mark.timeout(120)
def test_world_messages_carry_seven_features_per_anchor(live_run):
    assert live_run["got"], live_run["stderr"][-3000:]
    worlds = [w for w in live_run["worlds"] if w["objects"]]
    from percept.runtime.net.messages import World, decode

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
    assert status["gaze"] == {"enabled": False, "state": "off", "target": None}


@pytest.mark.timeout(120)
def test_sigterm_stops_cleanly_within_two_seconds(live_run):
    assert live_run["code"] == 0, live_run["stderr"][-3000:]
    assert live_run["seconds"] < 2.0
    assert "stopped in" in live_run["stderr"]


@pytest.mark.timeout(120)
def test_replay_reproduces_the_recorded_world_models(live_run):
    from percept.runtime.record.reader import Recording, read_recording
    from percept.runtime.record.replay import ReplayReport, replay

    recording = Recording(live_run["record"])
    kinds: dict[str, int] = {}
    searched: list[list[int]] = []
    for kind, item in read_recording(live_run["record"], recording):
        kinds[kind] = kinds.get(kind, 0) + 1
        if kind == "frame":
            searched.append(item.inputs["marker_frames"])
    assert not recording.truncated
    # The marker search ran on its own thread, on about every 3rd frame ([landmarks] every),
    # its results applied at later frames: the replay searches the same frames again.
    assert sum(map(len, searched)) >= len(searched) / 10
    assert kinds.get("frame", 0) >= 20 and kinds.get("world", 0) == kinds["frame"]
    report = ReplayReport()
    worlds = list(replay(live_run["record"], speed=None, report=report))
    assert report.frames == kinds["frame"] == len(worlds)
    assert report.differing == []
    assert report.matched == kinds["world"]


@pytest.mark.timeout(120)
def test_zenoh_subscribers_see_what_is_recorded(live_run):
    from percept.runtime.record.reader import read_recording

    recorded: dict[str, dict] = {"world": {}, "status": {}}
    for kind, item in read_recording(live_run["record"]):
        if kind == "world":
            recorded["world"][item["frame"]] = item
        elif kind == "status":
            recorded["status"][item["stamp"]] = item
    worlds = {w["frame"]: w for w in live_run["worlds"]}
    common = sorted(set(worlds) & set(recorded["world"]))
    assert len(common) >= 20
    for frame in common:
        assert worlds[frame] == recorded["world"][frame]
    assert {"t", "pose_fresh"} <= set(worlds[common[-1]])
    statuses = {s["stamp"]: s for s in live_run["statuses"]}
    both = sorted(set(statuses) & set(recorded["status"]))
    assert both
    for stamp in both:
        assert statuses[stamp] == recorded["status"][stamp]
    last = statuses[both[-1]]
    assert {"cpu", "cpu_threads", "rss_mb", "games", "frames"} <= set(last)
    # The threads that process frames and publish them are among those whose CPU is reported.
    assert {"perception", "camera", "publisher", "other"} <= set(last["cpu_threads"])


@pytest.mark.timeout(120)
def test_a_peer_that_exits_is_gone_at_once(live_run):
    """b's liveliness token goes with it: a's status says so without waiting for stale_after
    (the age would then be finite), and from the frame that saw it go, a locates b no more."""
    from percept.runtime.record.reader import read_recording

    assert live_run["peer_code"] == 0, live_run["peer_stderr"][-3000:]
    assert "servos read directly" in live_run["peer_stderr"]
    assert live_run["gone"], live_run["statuses"][-1]["peers"]
    went = None
    located_after = []
    for kind, item in read_recording(live_run["record"]):
        if kind == "frame" and went is None:
            events = [m for _, m in item.inputs["peer_messages"] if m.get("alive") is False]
            if any(m["robot"] == "b" for m in events):
                went = item.inputs["seq"]
        elif kind == "world" and went is not None and item["frame"] >= went:
            located_after.append("b" in item["peers"])
    assert went is not None and located_after and not any(located_after)


@pytest.mark.timeout(120)
def test_replay_uses_the_experiments_feature_model(live_run, tmp_path):
    """The same recording through the chapter's feature construction instead of the default
    cylinder fit: other positions, the same colours."""
    from percept.runtime.record.reader import read_recording
    from percept.runtime.record.replay import replay

    chapter = variant(live_run["experiment"], "chapter.toml", '[features]\nmodel = "chapter"')
    recorded = {w["frame"]: w for k, w in read_recording(live_run["record"]) if k == "world"}
    moved = same_colour = 0
    for world in replay(live_run["record"], experiment_path=chapter, speed=None):
        before = {o["id"]: o for o in recorded[world["frame"]]["objects"]}
        for obj in world["objects"]:
            old = before[obj["id"]]["features"]
            same_colour += obj["features"]["luminance"] == old["luminance"]
            if obj["on_ground"] and obj["features"]["x"] != old["x"]:
                moved += 1
    assert moved >= 20 and same_colour >= moved


def test_refuses_a_profile_the_scene_does_not_simulate(tmp_path):
    experiment = experiment_copy(tmp_path)
    myon = ROOT / "config" / "robots" / "myon.toml"
    proc = start_daemon(experiment, "a", "--robot", str(myon))
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2
    assert "robots[0].profile: robot 'a' is simulated with the camera and chain of" in err.decode()


def test_refuses_a_servo_model_of_the_other_protocol(tmp_path):
    op3 = (ROOT / "config" / "robots" / "robotis-op3.toml").read_text(encoding="utf-8")
    assert "protocol = 2.0" in op3
    wrong = tmp_path / "op3-protocol-1.toml"
    wrong.write_text(op3.replace("protocol = 2.0", "protocol = 1.0"), encoding="utf-8")
    proc = start_daemon(experiment_copy(tmp_path), "a", "--robot", str(wrong))
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2
    assert f"{wrong}: joints[0].model: servo model" in err.decode()
    assert "speaks Protocol 2.0, not 1.0" in err.decode()


def _read_worlds(path: Path) -> tuple[int, int, int, object]:
    """(frames, world models, objects in them, the Recording) read from ``path``."""
    from percept.runtime.record.reader import Recording, read_recording

    recording = Recording(path)
    frames = worlds = objects = 0
    for kind, item in read_recording(path, recording):
        if kind == "frame":
            frames += 1
            assert item.image.ndim == 3
        elif kind == "world":
            worlds += 1
            objects += len(item["objects"])
    return frames, worlds, objects, recording


@pytest.mark.timeout(240)
def test_sigkill_leaves_a_readable_recording_that_a_restart_keeps(tmp_path):
    """SIGKILL, then the same ``percept run --record``: the killed file is kept as it was and
    reads to its last chunk (``percept stats`` too); the restart records to ``killed.1.mcap``.
    A second daemon with the same --record and the same port fails to start and leaves the
    running one's file alone."""
    from percept.perception.features.scaling import FeatureScaling
    from percept.runtime.cli import main

    experiment = experiment_copy(tmp_path)
    record = tmp_path / "killed.mcap"
    proc = start_daemon(experiment, "b", "--record", str(record))
    listener = Listener(endpoint(experiment, "b"), "b")
    try:
        seen = listener.wait(lambda s: sum(1 for w in s.worlds if w["objects"]) >= 20, 60)
        assert seen, "no objects in the world models"
        time.sleep(1.5)  # let at least one chunk be flushed after them
        code, _, _ = stop(proc, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            proc.kill()
        listener.close()
    assert code == -signal.SIGKILL
    killed = record.read_bytes()
    frames, worlds, objects, recording = _read_worlds(record)
    assert recording.truncated and not recording.damage.any
    assert frames >= 10 and worlds >= 10 and objects >= 10
    assert recording.metadata["robot"] == "b"
    out = tmp_path / "stats.toml"
    assert main(["stats", str(record), "--out", str(out)]) == 0
    assert max(s.n for s in FeatureScaling.load(out).stats.values()) == objects

    again = tmp_path / "killed.1.mcap"
    proc = start_daemon(experiment, "b", "--record", str(record))
    listener = Listener(endpoint(experiment, "b"), "b")
    second = None
    try:
        assert listener.wait(lambda s: len(s.worlds) >= 10, 60), "no world models after restart"
        time.sleep(1.0)
        growing = again.stat().st_size
        second = start_daemon(experiment, "b", "--record", str(record))
        _, second_err = second.communicate(timeout=60)  # it fails to bind b's port
        time.sleep(1.0)
        assert again.stat().st_size > growing, "the first daemon's file stopped growing"
        code, _, err = stop(proc)
    finally:
        for p in (proc, second):
            if p is not None and p.poll() is None:
                p.kill()
        listener.close()
    assert code == 0 and second.returncode > 0, second_err.decode(errors="replace")
    assert f"{record} exists and is kept: recording to {again}" in err
    assert record.read_bytes() == killed
    assert sorted(p.name for p in tmp_path.glob("*.mcap")) == ["killed.1.mcap", "killed.mcap"]
    frames, worlds, _, recording = _read_worlds(again)
    assert not recording.truncated and frames >= 10 and worlds >= 10


# foxglove-sdk 0.30 speaks the Foxglove WebSocket protocol as foxglove.sdk.v1 (it refuses a client
# offering only the spec's older name, foxglove.websocket.v1, with HTTP 400).
SUBPROTOCOL = "foxglove.sdk.v1"


def wait_listening(port: int, timeout: float) -> None:
    """Wait until something accepts TCP connections on 127.0.0.1:``port``."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


class FoxgloveClient:
    """A Foxglove WebSocket client on a connection ``ws``: the channels the server advertises,
    subscriptions, and the decoded messages received on them."""

    def __init__(self, ws) -> None:
        self.ws = ws
        self.channels: dict[str, dict] = {}
        self._subscribed: dict[int, str] = {}
        self.received: dict[str, list] = {}

    def subscribe(self, topic: str) -> None:
        sub = len(self._subscribed) + 1
        self._subscribed[sub] = topic
        subscription = {"id": sub, "channelId": self.channels[topic]["id"]}
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [subscription]}))

    def pump(self, until, timeout: float) -> bool:
        """Read messages until ``until(self)`` holds (True) or ``timeout`` seconds pass."""
        import struct

        deadline = time.monotonic() + timeout
        while not until(self):
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            try:
                data = self.ws.recv(timeout=left)
            except TimeoutError:
                return False
            if isinstance(data, str):
                message = json.loads(data)
                if message["op"] == "advertise":
                    self.channels.update({c["topic"]: c for c in message["channels"]})
            elif data[0] == 1:  # message data: opcode, subscription id, log time, payload
                (sub,) = struct.unpack_from("<I", data, 1)
                topic = self._subscribed[sub]
                self.received.setdefault(topic, []).append(self._decode(topic, data[13:]))
        return True

    def _decode(self, topic: str, payload: bytes):
        channel = self.channels[topic]
        if channel["encoding"] == "json":
            return json.loads(payload)
        import base64

        from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

        files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
        pool = descriptor_pool.DescriptorPool()
        for file in files.file:
            pool.Add(file)
        cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
        return cls.FromString(payload)


@pytest.mark.timeout(120)
def test_live_view_serves_camera_debug_images_and_map_to_a_foxglove_client(tmp_path):
    import cv2
    from websockets.sync.client import connect

    port = free_port()
    proc = start_daemon(experiment_copy(tmp_path), "a", "--view", str(port))
    live = ["/live/anchors", "/live/map", "/live/foreground", "/live/classes"]
    try:
        wait_listening(port, 60)
        with connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL]) as ws:
            client = FoxgloveClient(ws)
            # The camera and the world are advertised at once, the live images once perception
            # runs (they are drawn only while someone subscribes).
            topics = ["/camera/image", "/percept/world", *live]
            advertised = client.pump(lambda c: set(topics) <= set(c.channels), 60)
            assert advertised, sorted(client.channels)
            for topic in topics:
                client.subscribe(topic)
            got = client.pump(lambda c: all(c.received.get(t) for t in topics), 60)
        code, _, err = stop(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert got, {t: len(client.received.get(t, [])) for t in topics}
    assert code == 0, err[-3000:]
    for topic in ["/camera/image", *live]:
        assert client.channels[topic]["schemaName"] == "foxglove.CompressedImage"
        image = client.received[topic][-1]
        assert image.format == "jpeg"
        decoded = cv2.imdecode(np.frombuffer(image.data, np.uint8), cv2.IMREAD_COLOR)
        assert decoded is not None and decoded.shape[2] == 3
        if topic != "/live/map":
            assert decoded.shape[:2] == (200, 320)  # the OP3's camera
    world = client.received["/percept/world"][-1]
    assert world["robot"] == "a" and world["schema"] == "percept.world/2"


def test_recorded_camera_rotation_quaternions():
    """The /tf quaternions (numpy, not scipy's Rotation) against scipy, up to sign."""
    from scipy.spatial.transform import Rotation

    from percept.kinematics.pose import quaternion

    rotations = [*Rotation.random(500, random_state=3).as_matrix(), np.eye(3)]
    rotations += [np.diag(d) for d in ([1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0])]
    for R in rotations:
        q = np.array(quaternion(R))
        expected = Rotation.from_matrix(R).as_quat()
        assert min(np.abs(q - expected).max(), np.abs(q + expected).max()) < 1e-12
