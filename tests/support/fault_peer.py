"""Other processes on the network of a daemon under test: a peer robot and a bad sender.

``python -m tests.support.fault_peer peer EXPERIMENT NAME`` is robot NAME of the experiment as
far as a peer sees it: its Zenoh session (peer mode, liveliness token) and its box messages at
the box rate. It prints ``ready <monotonic time>`` after its first box message and runs until
killed.

``python -m tests.support.fault_peer send ENDPOINT KIND COUNT RATE`` is a colleague's script: a
Zenoh client on ENDPOINT that publishes COUNT payloads of KIND at RATE a second on the keys a
daemon subscribes to, prints ``start <t>`` before the first and ``end <t>`` after the last
(``time.monotonic()``, the same clock in every process of the machine) and exits. KIND:

- ``malformed``: cut-off JSON on ``percept/c/boxes``,
- ``wrong-schema``: a valid status message on ``percept/c/boxes``,
- ``oversized``: 300 kB of JSON on ``percept/c/boxes`` (the bound is 256 kB),
- ``forged``: robot c's boxes on robot b's key,
- ``many-keys``: cut-off JSON, each on a key of its own with a long made-up robot name,
- ``flood``: valid messages to robot a on every subscribed key in turn (boxes of robot c,
  pointing requests, start signals for games),
- ``far-boxes``: robot b's boxes, every field within the schema, one box 10 km away on each
  axis (14 km from b: implausible in any arena),
- ``strangers``: made-up robots ``c0``..``c9`` in turn, each under the flood rate, playing
  games with robot a: a pointing request, then the verdict ``success``;
- ``names``: liveliness tokens ``percept/<name>/alive`` of made-up names ``s0``, ``s1``, ...,
  each declared and withdrawn at once (COUNT names);
- ``long-names``: the same with names of 300 characters, which no robot can have;
- ``words``: a forged robot b teaching robot a a new word of 64 letters per guessing game: it
  sends robot a's own box poses as b's (so that a locates b where a stands), then per game an
  utterance of a made-up word and the feedback ``failure`` pointing at one of a's objects (from
  a's latest world model), which a, as hearer, learns the word for (COUNT games);
- ``huge``: payloads of 50 MB on each topic in turn, from robot b (COUNT payloads).
"""

from __future__ import annotations

import json
import random
import signal
import string
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import zenoh

KINDS = (
    "malformed",
    "wrong-schema",
    "oversized",
    "forged",
    "many-keys",
    "flood",
    "far-boxes",
    "strangers",
    "names",
    "long-names",
    "words",
    "huge",
)
HUGE = 50 * 1024 * 1024


def _payloads(kind: str, count: int) -> list[tuple[str, bytes]]:
    """(key, payload) of each message to send."""
    now = time.time()
    boxes = {"schema": "percept.boxes/1", "robot": "c", "stamp": now, "boxes": []}
    if kind == "malformed":
        return [("percept/c/boxes", json.dumps(boxes).encode()[:-7])] * count
    if kind == "wrong-schema":
        status = {"schema": "percept.status/1", "robot": "c", "stamp": now, "fps": 30.0}
        status |= {"dropped_frames": 0, "camera": {}, "servos": {}, "peers": {}}
        status |= {"rejected_messages": 0, "faults": []}
        return [("percept/c/boxes", json.dumps(status).encode())] * count
    if kind == "oversized":
        big = dict(boxes, padding="x" * 300_000)
        return [("percept/c/boxes", json.dumps(big).encode())] * count
    if kind == "forged":
        return [("percept/b/boxes", json.dumps(boxes).encode())] * count
    if kind == "many-keys":
        return [(f"percept/c{i:04d}{'x' * 200}/boxes", b"{") for i in range(count)]
    if kind == "flood":
        out = []
        for i in range(count):
            game = f"c-{i}"
            if i % 3 == 0:
                message = dict(boxes, stamp=now)
                key = "percept/c/boxes"
            elif i % 3 == 1:
                message = {"schema": "percept.pointing/1", "game": game, "from": "c", "to": "a"}
                message |= {"x": 0.5, "y": 0.0}
                key = "percept/c/pointing"
            else:
                message = {"schema": "percept.signal/1", "game": game, "from": "c", "to": "a"}
                message |= {"signal": "start", "speaker": "a", "hearer": "c"}
                key = "percept/c/signal"
            out.append((key, json.dumps(message).encode()))
        return out
    if kind == "far-boxes":
        box = {"id": 1, "x": 10000, "y": 10000, "theta": 0, "n": 1}
        far = dict(boxes, robot="b", boxes=[box])
        return [("percept/b/boxes", json.dumps(far).encode())] * count
    if kind == "strangers":
        out = []
        for i in range(count):
            robot, game = f"c{i // 2 % 10}", f"c-{i // 2}"
            if i % 2 == 0:
                message = {"schema": "percept.pointing/1", "x": 0.5, "y": 0.0}
                key = f"percept/{robot}/pointing"
            else:
                message = {"schema": "percept.signal/1", "signal": "success"}
                key = f"percept/{robot}/signal"
            message |= {"game": game, "from": robot, "to": "a"}
            out.append((key, json.dumps(message).encode()))
        return out
    if kind == "huge":
        topics = ("boxes", "pointing", "signal", "utterance", "guess", "feedback")
        big = b"x" * HUGE
        return [(f"percept/b/{topics[i % len(topics)]}", big) for i in range(count)]
    raise SystemExit(f"unknown kind {kind!r}; known: {', '.join(KINDS)}")


def _paced(count: int, rate: float, step: Callable[[int], None]) -> None:
    """``step(i)`` for i in 0..count-1 at ``rate`` a second, between ``start`` and ``end``."""
    period = 1.0 / rate
    began = time.monotonic()
    print(f"start {began:.6f}", flush=True)
    for i in range(count):
        step(i)
        delay = began + (i + 1) * period - time.monotonic()
        if delay > 0:
            time.sleep(delay)
    print(f"end {time.monotonic():.6f}", flush=True)


class _Forger:
    """Robot b as a forger sees it: a's box poses sent as b's, a's objects where a sees them."""

    def __init__(self, session: zenoh.Session) -> None:
        self.session = session
        self.objects: list[tuple[float, float]] = []
        self.lock = threading.Lock()
        session.declare_subscriber("percept/a/boxes", self._on_boxes)
        session.declare_subscriber("percept/a/world", self._on_world)

    def _on_boxes(self, sample: zenoh.Sample) -> None:
        boxes = json.loads(sample.payload.to_bytes())
        boxes |= {"robot": "b", "stamp": time.time()}
        self.session.put("percept/b/boxes", json.dumps(boxes).encode())

    def _on_world(self, sample: zenoh.Sample) -> None:
        world = json.loads(sample.payload.to_bytes())
        places = [(o["features"].get("x"), o["features"].get("y")) for o in world["objects"]]
        with self.lock:
            self.objects = [(x, y) for x, y in places if x is not None and y is not None]

    def teach(self, i: int) -> None:
        with self.lock:
            objects = list(self.objects)
        game, word = f"b-{i}", "".join(random.choices(string.ascii_lowercase, k=64))
        said = {"schema": "percept.utterance/1", "game": game, "from": "b", "to": "a"}
        self.session.put("percept/b/utterance", json.dumps(said | {"word": word}).encode())
        if objects:
            x, y = random.choice(objects)
            told = {"schema": "percept.feedback/1", "game": game, "from": "b", "to": "a"}
            told |= {"signal": "failure", "x": x, "y": y}
            time.sleep(0.005)  # after a's guess, as a speaker's feedback comes
            self.session.put("percept/b/feedback", json.dumps(told).encode())


def send(endpoint: str, kind: str, count: int, rate: float) -> None:
    import zenoh

    from percept.runtime.net.zenoh_config import config

    settings = {
        "mode": "client",
        "connect": {"endpoints": [endpoint], "timeout_ms": -1},
        "scouting": {"multicast": {"enabled": False}},
    }
    session = zenoh.open(config(settings))
    if kind in ("names", "long-names"):
        pad = "x" * 300 if kind == "long-names" else ""
        liveliness = session.liveliness()

        def token(i: int) -> None:
            liveliness.declare_token(f"percept/s{i}{pad}/alive").undeclare()

        _paced(count, rate, token)
    elif kind == "words":
        forger = _Forger(session)
        time.sleep(2.0)  # a's boxes sent as b's: a locates b before the first game
        _paced(count, rate, forger.teach)
    else:
        payloads = _payloads(kind, count)
        publishers = {key: session.declare_publisher(key) for key in {k for k, _ in payloads}}
        _paced(count, rate, lambda i: publishers[payloads[i][0]].put(payloads[i][1]))
    session.close()


def peer(experiment_path: str, name: str) -> None:
    from percept.runtime.net.link import Link
    from percept.runtime.net.peers import BoxPublisher
    from percept.runtime.settings.experiment import load_experiment

    experiment = load_experiment(experiment_path)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    with Link(experiment, name) as link:
        publisher = BoxPublisher(link, name, lambda: [], experiment.peers.box_rate).start()
        while publisher.sent == 0 and not done.wait(0.01):
            pass
        print(f"ready {time.monotonic():.6f}", flush=True)
        done.wait()
        publisher.stop()


def main(argv: list[str]) -> None:
    if argv[:1] == ["peer"] and len(argv) == 3:
        peer(argv[1], argv[2])
    elif argv[:1] == ["send"] and len(argv) == 5:
        send(argv[1], argv[2], int(argv[3]), float(argv[4]))
    else:
        raise SystemExit(__doc__)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    main(sys.argv[1:])
