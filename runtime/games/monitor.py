"""The joint-attention monitor: a program that reads every robot's world model and says when two
robots observe the same set of objects (SPEC §4.7, chapter 5.3.2), then starts a game.

Two world models are compared in one frame: robot a's, with robot b's objects carried over by
a's estimate of b's pose (or, failing that, the inverse of b's estimate of a's). The sets are the
objects each robot sees (not those it remembers out of sight); they are the same when every object
of each has a partner in the other within the gate (one to one, by the assignment of least total
distance) and neither is empty.
"""

from __future__ import annotations

import itertools
import logging
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, NotRequired, TypedDict

import numpy as np

from percept.runtime.games.pointing import Located, located
from percept.runtime.net.messages import Message, ObjectId, PeerPose, Signal, World
from percept.runtime.net.peers import inverse, to_my_frame
from percept.runtime.net.settings import PeerSettings

if TYPE_CHECKING:
    from percept.runtime.net.link import Link

log = logging.getLogger("percept.monitor")


def same_objects(
    mine: list[Located], theirs_in_my_frame: list[Located], gate: float
) -> list[tuple[ObjectId, ObjectId]] | None:
    """The pairs (my id, their id) when both sets hold the same objects, else None."""
    if not mine or len(mine) != len(theirs_in_my_frame):
        return None
    from scipy.optimize import linear_sum_assignment

    a = np.array([(o.x, o.y) for o in mine])
    b = np.array([(o.x, o.y) for o in theirs_in_my_frame])
    cost = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    if np.any(cost[rows, cols] > gate):
        return None
    return [(mine[i].id, theirs_in_my_frame[j].id) for i, j in zip(rows, cols, strict=True)]


class AttentionEvent(TypedDict):
    """What the monitor announces (``percept monitor`` prints it as a JSON line): ``event``
    ``joint_attention`` or ``attention_lost``, the two ``robots``, the wall-clock ``stamp``; on
    joint attention the ``objects`` pairs (a's id, b's id) and, when a game is started, its id,
    speaker and hearer."""

    event: str
    robots: list[str]
    stamp: float
    objects: NotRequired[list[list[ObjectId]]]
    game: NotRequired[str]
    speaker: NotRequired[str]
    hearer: NotRequired[str]


@dataclass(frozen=True)
class Attention:
    """Robots ``a`` and ``b`` observe the same objects: ``pairs`` of (a's id, b's id)."""

    a: str
    b: str
    pairs: tuple[tuple[ObjectId, ObjectId], ...]


class AttentionMonitor:
    """Keeps each robot's latest world model and announces when pairs of robots start or stop
    observing the same set of objects. Thread-safe; feed it with :meth:`on_world`."""

    def __init__(
        self,
        robots: list[str],
        settings: PeerSettings | None = None,
        announce: Callable[[AttentionEvent], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.robots = list(robots)
        self.settings = settings or PeerSettings()
        self._announce = announce or (lambda event: None)
        self._clock = clock
        self._worlds: dict[str, tuple[float, World]] = {}
        self._joint: dict[tuple[str, str], Attention] = {}
        self._lock = threading.Lock()

    def on_world(self, world: World) -> None:
        """A robot's world model arrived."""
        if world.robot not in self.robots:
            return
        with self._lock:
            self._worlds[world.robot] = (self._clock(), world)
            for pair in itertools.combinations(self.robots, 2):
                if world.robot in pair:
                    self._update(pair)

    def on_alive(self, name: str, alive: bool) -> None:
        """A robot that is gone observes nothing."""
        if alive:
            return
        with self._lock:
            self._worlds.pop(name, None)
            for pair in list(self._joint):
                if name in pair:
                    self._update(pair)

    def joint(self) -> list[Attention]:
        """The pairs of robots observing the same objects now."""
        with self._lock:
            return list(self._joint.values())

    def _world(self, robot: str) -> World | None:
        entry = self._worlds.get(robot)
        if entry is None or self._clock() - entry[0] > self.settings.stale_after:
            return None
        return entry[1]

    def _update(self, pair: tuple[str, str]) -> None:
        a, b = pair
        attention = self._compare(a, b)
        before = self._joint.get(pair)
        if attention is not None:
            self._joint[pair] = attention
        else:
            self._joint.pop(pair, None)
        if (before is None) != (attention is None):
            event: AttentionEvent = {
                "event": "joint_attention" if attention else "attention_lost",
                "robots": [a, b],
                "stamp": time.time(),
            }
            if attention is not None:
                event["objects"] = [list(p) for p in attention.pairs]
            self._announce(event)

    def _compare(self, a: str, b: str) -> Attention | None:
        world_a, world_b = self._world(a), self._world(b)
        if world_a is None or world_b is None:
            return None
        pose: PeerPose | None = world_a.peers.get(b)
        if pose is None and a in world_b.peers:
            pose = inverse(world_b.peers[a])
        if pose is None:
            return None
        seen_a = [o for o in located(world_a) if o.visible]
        carried = [
            Located(o.id, *to_my_frame(pose, o.x, o.y)) for o in located(world_b) if o.visible
        ]
        pairs = same_objects(seen_a, carried, self.settings.attention_gate)
        return Attention(a, b, tuple(pairs)) if pairs is not None else None


class MonitorService:
    """The monitor on the network: subscribes to every world model and liveliness token, prints
    events, and on joint attention sends ``start`` to both robots (speakers taking turns)."""

    def __init__(
        self,
        link: Link,
        robots: list[str],
        settings: PeerSettings | None = None,
        emit: Callable[[AttentionEvent], None] | None = None,
        start_games: bool = True,
    ) -> None:
        self.link = link
        self._emit = emit or (lambda event: None)
        self._start_games = start_games
        self._turn = itertools.count()
        self.monitor = AttentionMonitor(robots, settings, self._on_event)
        link.subscribe("world", self._on_world)
        link.watch_alive(self.monitor.on_alive)

    def _on_world(self, message: Message) -> None:
        if isinstance(message, World):
            self.monitor.on_world(message)

    def _on_event(self, event: AttentionEvent) -> None:
        log.info("%s: %s", event["event"], " and ".join(event["robots"]))
        if event["event"] == "joint_attention" and self._start_games:
            a, b = event["robots"]
            speaker, hearer = (a, b) if next(self._turn) % 2 == 0 else (b, a)
            game = f"{self.link.name}-{secrets.token_hex(4)}"
            for robot in (speaker, hearer):
                self.link.publish(
                    "signal", Signal(game, self.link.name, robot, "start", speaker, hearer)
                )
            event = {**event, "game": game, "speaker": speaker, "hearer": hearer}
        self._emit(event)
