"""Messages (schemas, validation, bounds) and the Zenoh link between real sessions."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import threading
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from zenoh import CongestionControl

from percept.perception.landmarks.records import BoxPose
from percept.runtime.net.link import Link, LinkError, NameTaken
from percept.runtime.net.messages import (
    MAX_PAYLOAD,
    SCHEMAS,
    Boxes,
    MessageError,
    World,
    WorldObject,
    decode,
    encode,
)
from percept.runtime.net.settings import NetworkSettings
from tests.support.messages import MESSAGES, NOW, WORLD
from tests.support.polling import wait_for
from tests.support.zenoh_rig import PROFILE, experiment, free_port

FIELDS = [
    "robot", "stamp", "boxes", "frame", "camera", "objects", "peers", "fps", "dropped_frames",
    "servos", "rejected_messages", "faults", "game", "from", "to", "x", "y", "object", "signal",
    "speaker", "hearer", "t", "pose_fresh", "ms_per_frame", "frames", "old_joint_frames",
    "frames_without_joints", "background", "inbox_dropped", "games", "cpu", "cpu_threads", "rss_mb",
    "recording",
    "word", "play", "objects", "visible", "last_seen",
]  # fmt: skip


@pytest.mark.parametrize("message", MESSAGES, ids=lambda m: type(m).__name__)
def test_round_trip(message: object) -> None:
    payload = encode(message)  # type: ignore[arg-type]
    assert json.loads(payload)["schema"] == message.SCHEMA  # type: ignore[attr-defined]
    assert decode(payload) == message
    assert decode(payload, message.SCHEMA) == message  # type: ignore[attr-defined]


def _boxes(**change: object) -> bytes:
    body = {"schema": "percept.boxes/1", "robot": "a", "stamp": NOW, "boxes": []}
    body.update(change)
    return json.dumps(body).encode()


def _utterance(**change: object) -> bytes:
    body = {"schema": "percept.utterance/1", "game": "g", "from": "a", "to": "b", "word": "ba"}
    return json.dumps({**body, **change}).encode()


def _feedback(**change: object) -> bytes:
    body = {"schema": "percept.feedback/1", "game": "g", "from": "a", "to": "b"}
    return json.dumps({**body, "signal": "failure", **change}).encode()


def _changed(message: object, **change: object) -> bytes:
    body = json.loads(encode(message))  # type: ignore[arg-type]
    body.update(change)
    return json.dumps(body).encode()


@pytest.mark.parametrize(
    ("payload", "problem"),
    [
        (b"", "not a JSON message"),
        (b"\xff\xfe{}", "not a JSON message"),
        (b"[1, 2]", "expected an object"),
        (b"[" * 50000 + b"]" * 50000, "not a JSON message"),
        (b'{"schema": "percept.boxes/2"}', "unknown schema"),
        (b'{"schema": "percept.boxes/1", "robot": "a", "stamp": NaN, "boxes": []}', "NaN"),
        (_boxes(stamp=-1), "stamp"),
        (_boxes(stamp="now"), "expected a number"),
        (_boxes(robot="a/b"), "robot"),
        (_boxes(robot="a\n"), "robot"),  # a pattern's "$" would let the newline through
        (_boxes(robot="b" * 65), "robot"),
        (_boxes(boxes=[{"id": 1, "x": 1e9, "y": 0, "theta": 0}]), "boxes[0].x"),
        (_boxes(boxes=[{"id": True, "x": 0, "y": 0, "theta": 0}]), "expected an integer"),
        (_boxes(boxes=[{"id": 1, "x": 0, "y": 0, "theta": 10**400}]), "theta"),
        (_boxes(boxes=[{"id": 1, "x": 0, "y": 0}]), "missing 'theta'"),
        (_boxes(boxes=[{"id": i, "x": 0, "y": 0, "theta": 0} for i in range(300)]), "at most"),
        (_boxes(filler="x" * MAX_PAYLOAD), "more than"),
        (b'{"schema": "percept.signal/1", "game": "g", "from": "a", "to": "b"}', "signal"),
        (b'{"schema":"percept.signal/1","game":"g","from":"a","to":"b","signal":"yes"}', "one of"),
        (_changed(MESSAGES[3], games={"played": 1.5}), "games.played"),
        (_changed(MESSAGES[3], cpu=-0.1), "cpu"),
        (_changed(MESSAGES[3], frames="many"), "frames"),
        (_changed(WORLD, pose_fresh=1), "pose_fresh"),
        (_changed(WORLD, t="now"), ".t"),
        (_utterance(word="Hello world"), "word"),
        (_utterance(word="a" * 65), "word"),
        (_utterance(word=7), "word"),
        (_utterance(word="hello\n"), "word"),
        (_utterance(to=None), "to"),
        (b'{"schema": "percept.utterance/1", "game": "g", "from": "a", "to": "b"}', "word"),
        (_utterance(schema="percept.guess/1", object=[1]), "object"),
        (_feedback(signal="maybe"), "one of"),
        (_feedback(signal="start"), "one of"),
        (_feedback(x=1e9, y=0.0), ".x"),
        (_feedback(game="a game"), "game"),
        (_changed(MESSAGES[10], play="hide-and-seek"), "play"),
        (_changed(MESSAGES[10], objects=[{"id": 1}]), "objects[0]"),
    ],
)
def test_bad_payloads_raise_message_error_only(payload: bytes, problem: str) -> None:
    with pytest.raises(MessageError, match=re.escape(problem)):
        decode(payload)


def test_wrong_schema_for_the_key() -> None:
    with pytest.raises(MessageError, match=r"expected schema percept\.boxes/1"):
        decode(encode(WORLD), Boxes.SCHEMA)


def test_world_objects_say_whether_they_are_seen_and_when_they_were_last() -> None:
    body = json.loads(encode(WORLD))
    assert body["schema"] == "percept.world/2"
    assert [(o["visible"], o["last_seen"]) for o in body["objects"]] == [
        (True, None),
        (True, None),
        (False, NOW - 12),
    ]
    body["objects"][2]["last_seen"] = -1
    with pytest.raises(MessageError, match=r"objects\[2\]\.last_seen"):
        decode(json.dumps(body).encode())


def test_a_version_1_world_model_is_read_as_objects_seen() -> None:
    """Recordings and peers of percept.world/1 (no visible, no last_seen) still read, also on
    the world key, which carries percept.world/2 now."""
    body = json.loads(encode(WORLD))
    for o in body["objects"]:
        del o["visible"], o["last_seen"]
    old = json.dumps({**body, "schema": "percept.world/1"}).encode()
    world = decode(old, World.SCHEMA)
    assert isinstance(world, World) and len(world.objects) == 3
    assert all(o.visible and o.last_seen is None for o in world.objects)
    assert world.objects[0] == WORLD.objects[0]


def test_unknown_fields_are_ignored() -> None:
    assert decode(_boxes(firmware="1.2", extra={"a": [1, 2]})) == Boxes("a", NOW, ())


def test_oversized_message_is_not_sent() -> None:
    many = tuple(
        WorldObject(i, (0.0, 0.0, 1.0, 1.0), {f"feature_{k}": 1.0 for k in range(60)})
        for i in range(1000)
    )
    with pytest.raises(MessageError, match="more than"):
        encode(World("a", NOW, 1, WORLD.camera, many))


@pytest.mark.timeout(60)
def test_two_sessions_trade_messages_and_count_bad_ones() -> None:
    exp = experiment("a", "b")
    boxes: list[object] = []
    worlds: list[object] = []
    with Link(exp, "a") as a, Link(exp, "b") as b:
        b.subscribe("boxes", boxes.append)
        b.subscribe("world", worlds.append)
        sent = Boxes("a", NOW, (BoxPose(4, 1.0, 2.0, 0.5, 2),))
        # Publish until b's subscription has reached a (declarations travel asynchronously).
        assert wait_for(lambda: a.publish("boxes", sent) or boxes, 10.0)
        a.publish("world", WORLD.to_json())  # a mapping is checked, then sent
        bad = [
            b"not json",
            encode(WORLD),  # right message, wrong key
            _boxes(robot="b"),  # a speaking for b
            _boxes(filler="x" * MAX_PAYLOAD),
        ]
        for payload in bad:
            # blocking: Zenoh's default drops a put on a congested queue, and each is counted
            a.session.put("percept/a/boxes", payload, congestion_control=CongestionControl.BLOCK)
        assert wait_for(lambda: b.rejected == len(bad) and worlds)
        assert all(m == sent for m in boxes) and worlds == [WORLD]
        assert a.listened("boxes") and not a.listened("status")  # nobody subscribes to status
        assert b.rejected_by_key["percept/a/boxes"] == len(bad)
        assert a.rejected == 0
        with pytest.raises(MessageError):
            a.publish("boxes", {"robot": "a", "stamp": NOW, "boxes": [{"id": -1}]})
        with pytest.raises(MessageError, match="does not go on"):
            a.publish("boxes", WORLD)


@pytest.mark.timeout(60)
def test_slow_handler_drops_oldest_and_never_stalls_zenoh() -> None:
    exp = experiment("a", "b", network=NetworkSettings(queue=4))
    seen: list[int] = []
    release = threading.Event()

    def slow(message: object) -> None:
        n = len(message.boxes)  # type: ignore[attr-defined]
        if n:  # the empty ones only open the route
            release.wait(5.0)
        seen.append(n)

    with Link(exp, "a") as a, Link(exp, "b") as b:
        b.subscribe("boxes", slow)
        assert wait_for(lambda: a.publish("boxes", Boxes("a", NOW, ())) or seen, 10.0)
        for n in range(1, 51):
            a.publish("boxes", Boxes("a", NOW, tuple(BoxPose(i, 0, 0, 0) for i in range(n))))
        # Zenoh keeps delivering while the handler is stuck: the link drops the oldest.
        assert wait_for(lambda: b.dropped >= 40)
        release.set()
        assert wait_for(lambda: seen[-1] == 50)  # the newest is handled
        handled = [n for n in seen if n]
        assert handled == sorted(handled) and len(handled) + b.dropped >= 50


@pytest.mark.timeout(60)
def test_a_client_at_one_robot_sees_every_robots_keys() -> None:
    exp = experiment("a", "b")
    client = NetworkSettings(mode="client", connect=(exp.robot("a").endpoint,))
    got: list[object] = []
    with Link(exp, "a"), Link(exp, "b") as b, Link(exp, "tool", client) as tool:
        tool.subscribe("boxes", got.append)
        sent = Boxes("b", NOW, ())
        assert wait_for(lambda: b.publish("boxes", sent) or got, 10.0)
        assert got[0] == sent


_PEER = """
import sys
from pathlib import Path
from percept.runtime.settings.experiment import Experiment, RobotEntry
from percept.runtime.net.link import Link
robots = tuple(RobotEntry(n, Path("x"), e) for n, e in zip("ab", sys.argv[1:3]))
link = Link(Experiment(name="t", robots=robots), "a")
print("ready", flush=True)
sys.stdin.read()  # until the test closes our stdin: then exit normally (atexit closes the link)
"""


@pytest.mark.timeout(60)
@pytest.mark.parametrize("how", ["exit", "kill"])
def test_a_peer_that_ends_is_noticed_within_a_second(how: str) -> None:
    exp = experiment("a", "b")
    events: list[tuple[float, str, bool]] = []
    with Link(exp, "b") as b:
        b.watch_alive(lambda name, alive: events.append((time.monotonic(), name, alive)))
        endpoints = [r.endpoint for r in exp.robots]
        peer = subprocess.Popen(
            [sys.executable, "-c", _PEER, *endpoints],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            encoding="utf-8",
        )
        try:
            assert peer.stdout is not None and peer.stdout.readline().strip() == "ready"
            assert wait_for(lambda: b.alive("a") is True, 20.0)
            ended = time.monotonic()
            if how == "exit":
                peer.stdin.close()  # type: ignore[union-attr]
            else:
                peer.send_signal(signal.SIGKILL)
            assert wait_for(lambda: b.alive("a") is False, 5.0)
        finally:
            peer.kill()
            peer.wait()
        (noticed,) = [t for t, name, alive in events if name == "a" and not alive]
        assert noticed - ended < 1.0


@pytest.mark.timeout(60)
def test_one_name_one_process_refused_at_start_or_reported_by_both_later() -> None:
    import zenoh

    from percept.runtime.net.zenoh_config import peer_config
    from percept.runtime.settings.experiment import Experiment, RobotEntry

    exp = experiment("a", "b")
    with Link(exp, "a", exclusive=True) as first, Link(exp, "b"):
        # A second a reaching the first through b (a peer of a peer) is refused at start.
        began = time.monotonic()
        with pytest.raises(NameTaken, match="another process already runs as 'a'"):
            Link(exp, "a", listen=[f"tcp/127.0.0.1:{free_port()}"], exclusive=True)
        assert time.monotonic() - began < 2.0
        assert first.clashes == []
    # Two a's that met nobody at their start, joined later by a process dialling both.
    ends = [f"tcp/127.0.0.1:{free_port()}" for _ in range(3)]
    others = [
        Experiment(
            name="x", robots=(RobotEntry("a", PROFILE, ep), RobotEntry("b", PROFILE, ends[2]))
        )
        for ep in ends[:2]
    ]
    with Link(others[0], "a", exclusive=True) as one:
        with Link(others[1], "a", exclusive=True) as two:
            assert one.clashes == two.clashes == []
            bridge = zenoh.open(peer_config([], ends[:2]))
            try:
                assert wait_for(lambda: one.clashes and two.clashes, 5.0)
                assert one.clashes != two.clashes  # each names the other session
            finally:
                bridge.close()
        assert wait_for(lambda: one.clashes == [], 5.0)


def test_closed_link_refuses_to_publish() -> None:
    exp = experiment("a")
    link = Link(exp, "a")
    link.close()
    link.close()  # idempotent
    with pytest.raises(LinkError, match="closed"):
        link.publish("boxes", Boxes("a", NOW, ()))


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400) | st.text(max_size=200).map(str.encode))
def test_any_bytes_decode_or_raise_message_error(payload: bytes) -> None:
    try:
        message = decode(payload)
    except MessageError:
        return
    assert decode(encode(message)) == message


_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=20,
)


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(SCHEMAS), st.dictionaries(st.sampled_from(FIELDS), _JSON, max_size=8))
def test_any_fields_decode_or_raise_message_error(schema: str, fields: dict) -> None:
    try:
        payload = json.dumps({"schema": schema, **fields}).encode()
    except ValueError:
        return
    try:
        message = decode(payload)
    except MessageError:
        return
    assert schema == message.SCHEMA and decode(encode(message)) == message


@pytest.mark.timeout(60)
def test_liveliness_names_are_checked_at_start_and_while_running() -> None:
    """A token ``percept/<name>/alive`` whose name no robot can have (longer than 64
    characters here, 300) never reaches a handler, whether it was there before the link watched
    or came later: it is rejected and counted like a bad message."""
    exp = experiment("a", "b")
    long_name = "m" * 300
    seen: list[tuple[str, bool]] = []
    with Link(exp, "a") as a:
        before = a.session.liveliness().declare_token(f"percept/{long_name}/alive")
        with Link(exp, "b") as b:
            b.watch_alive(lambda name, alive: seen.append((name, alive)))
            assert wait_for(lambda: ("a", True) in seen, 20.0)
            assert wait_for(lambda: b.rejected == 1, 5.0)
            later = a.session.liveliness().declare_token(f"percept/{long_name}x/alive")
            assert wait_for(lambda: b.rejected == 2, 5.0)
            later.undeclare()
            before.undeclare()
            time.sleep(0.3)
            assert all(len(name) <= 64 for name, _ in seen), seen
            assert b.alive(long_name) is None
            assert b.rejected_by_key[f"percept/{long_name}/alive"] >= 1


@pytest.mark.timeout(60)
def test_liveliness_names_remembered_are_bounded_and_gone_ones_forgotten_first() -> None:
    from percept.runtime.net.link import NAMES_KEPT

    exp = experiment("a", "b")
    with Link(exp, "a") as a, Link(exp, "b") as b:
        b.watch_alive(lambda *_: None)
        assert wait_for(lambda: b.alive("a") is True, 20.0)
        liveliness = a.session.liveliness()
        for i in range(NAMES_KEPT + 100):
            liveliness.declare_token(f"percept/stranger{i}/alive").undeclare()
        last = f"stranger{NAMES_KEPT + 99}"
        assert wait_for(lambda: b.alive(last) is False, 10.0)
        assert len(b._alive) <= NAMES_KEPT
        assert b.alive("a") is True  # present, so kept while gone strangers were forgotten


@pytest.mark.timeout(60)
def test_a_payload_beyond_zenohs_bound_is_never_put_together_and_the_link_goes_on() -> None:
    """50 MB on a key a robot listens to: Zenoh drops it as its fragments come (it never reaches
    the link, which counts nothing), and the next message on the same session arrives."""
    from percept.runtime.net.zenoh_config import RX_MOST

    exp = experiment("a", "b")
    got: list[object] = []
    with Link(exp, "a") as a, Link(exp, "b") as b:
        b.subscribe("boxes", got.append)
        assert wait_for(lambda: a.publish("boxes", Boxes("a", NOW, ())) or got, 10.0)
        a.session.put("percept/a/boxes", b"x" * (50 * 1024 * 1024))
        a.session.put("percept/a/boxes", b"y" * (RX_MOST // 2 + 1))  # oversized, yet counted
        sent = Boxes("a", NOW, (BoxPose(4, 1.0, 2.0, 0.5, 2),))
        a.publish("boxes", sent)
        assert wait_for(lambda: got[-1] == sent, 10.0)
        assert b.rejected == 1 and b.dropped == 0
