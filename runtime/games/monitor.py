"""The joint-attention monitor: a program that reads every robot's world model and says when two
robots attend to objects together (SPEC §4.7, chapter 5.3.2), and starts games while they do.

Two world models are compared in one frame: robot a's, with robot b's objects carried over by
a's estimate of b's pose (or, failing that, the inverse of b's estimate of a's). Objects of the
two are paired one to one by the assignment of least total distance, a pair within the gate being
one object both see (or remember: whatever the world models hold). Two rules say when that is
joint attention (``[peers] attention``):

- ``shared`` (the default): the pairs are a context of at least ``attention_least`` objects; the
  objects only one robot sees, hidden from the other or outside its view, are left out. In a busy
  scene, where something is always hidden from one of the robots, this is what lets games happen;
- ``same``, the chapter's rule: every object of each has a partner and neither set is empty.

While two robots attend jointly the monitor starts the experiment's games (``[peers] games``,
speakers taking turns) every ``game_interval`` seconds, telling each robot its anchors of the
context (the start signal's ``objects``).
"""

from __future__ import annotations

import itertools
import logging
import math
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, NotRequired, TypedDict

import numpy as np

from percept.perception.assignment import linear_sum_assignment
from percept.runtime.games.pointing import Located, located
from percept.runtime.net.messages import Message, ObjectId, PeerPose, Signal, World
from percept.runtime.net.peers import inverse, to_my_frame
from percept.runtime.net.settings import PeerSettings

if TYPE_CHECKING:
    from percept.runtime.net.link import Link

log = logging.getLogger("percept.monitor")


Pairs = list[tuple[ObjectId, ObjectId]]


def _pairs(mine: list[Located], theirs_in_my_frame: list[Located], gate: float) -> Pairs:
    """(my id, their id) of the objects both see: paired one to one by the assignment of least
    total distance among the pairs within ``gate``."""
    if not mine or not theirs_in_my_frame:
        return []
    a = np.array([(o.x, o.y) for o in mine])
    b = np.array([(o.x, o.y) for o in theirs_in_my_frame])
    cost = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    # A pairing beyond the gate is no pair: at one cost for all, it cannot steer the others.
    rows, cols = linear_sum_assignment(np.where(cost <= gate, cost, gate + 1e6))
    return [
        (mine[i].id, theirs_in_my_frame[j].id)
        for i, j in zip(rows, cols, strict=True)
        if cost[i, j] <= gate
    ]


def same_objects(
    mine: list[Located], theirs_in_my_frame: list[Located], gate: float
) -> Pairs | None:
    """The pairs (my id, their id) when both sets hold the same objects, else None."""
    if not mine or len(mine) != len(theirs_in_my_frame):
        return None
    pairs = _pairs(mine, theirs_in_my_frame, gate)
    return pairs if len(pairs) == len(mine) else None


def shared_objects(
    mine: list[Located], theirs_in_my_frame: list[Located], gate: float, least: int = 1
) -> Pairs | None:
    """The pairs (my id, their id) of the objects both see when there are at least ``least``
    (and one), else None."""
    pairs = _pairs(mine, theirs_in_my_frame, gate)
    return pairs if len(pairs) >= max(1, least) else None


class AttentionEvent(TypedDict):
    """What the monitor announces (``percept monitor`` prints it as a JSON line): ``event``
    ``joint_attention`` or ``attention_lost``, the two ``robots``, the wall-clock ``stamp``; on
    joint attention the ``objects`` pairs (a's id, b's id) and, when a game is started, its id,
    speaker, hearer and the game it is (``play``). ``game``: a game started while the robots
    still attend jointly (as many as the game interval allows)."""

    event: str
    robots: list[str]
    stamp: float
    objects: NotRequired[list[list[ObjectId]]]
    game: NotRequired[str]
    speaker: NotRequired[str]
    hearer: NotRequired[str]
    play: NotRequired[str]


@dataclass(frozen=True)
class Attention:
    """Robots ``a`` and ``b`` attend jointly to the objects ``pairs`` (a's id, b's id)."""

    a: str
    b: str
    pairs: tuple[tuple[ObjectId, ObjectId], ...]


class AttentionMonitor:
    """Keeps each robot's latest world model and announces when pairs of robots start or stop
    attending jointly (the rule of ``settings.attention``). Thread-safe; feed it with
    :meth:`on_world`."""

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
        """The pairs of robots attending jointly now, with their objects."""
        with self._lock:
            return list(self._joint.values())

    def waiting_for(self) -> str:
        """What the monitor waits for now, in words (or the joint attention it sees)."""
        if len(self.robots) < 2:
            return f"joint attention needs two robots; the experiment has {len(self.robots)}"
        with self._lock:
            silent = [r for r in self.robots if self._world(r) is None]
            if silent:
                return f"waiting for the world models of {', '.join(silent)}"
            said = []
            for a, b in itertools.combinations(self.robots, 2):
                if (a, b) in self._joint:
                    said.append(f"{a} and {b} attend jointly")
                    continue
                world_a, world_b = self._world(a), self._world(b)
                if world_a is not None and world_b is not None:
                    if b not in world_a.peers and a not in world_b.peers:
                        said.append(f"waiting for {a} or {b} to locate the other (its markers)")
                    else:
                        said.append(f"waiting for {a} and {b} to see the same objects")
            return "; ".join(said)

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
        carried = [Located(o.id, *to_my_frame(pose, o.x, o.y)) for o in located(world_b)]
        gate = self.settings.attention_gate
        if self.settings.attention == "same":
            pairs = same_objects(located(world_a), carried, gate)
        else:
            pairs = shared_objects(located(world_a), carried, gate, self.settings.attention_least)
        return Attention(a, b, tuple(pairs)) if pairs is not None else None


class MonitorService:
    """The monitor on the network: subscribes to every world model and liveliness token, prints
    events, and while two robots attend jointly sends ``start`` to both every game interval, for
    each of the experiment's games (speakers taking turns)."""

    def __init__(
        self,
        link: Link,
        robots: list[str],
        settings: PeerSettings | None = None,
        emit: Callable[[AttentionEvent], None] | None = None,
        start_games: bool = True,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.link = link
        self.settings = settings or PeerSettings()
        self._emit = emit or (lambda event: None)
        self._start_games = start_games
        self._clock = clock
        self._turn = itertools.count()
        self._started: dict[tuple[str, str], float] = {}  # when the last games of a pair began
        self._lock = threading.Lock()
        self.monitor = AttentionMonitor(robots, self.settings, self._on_event, clock)
        link.subscribe("world", self._on_world)
        link.watch_alive(self.monitor.on_alive)

    def _on_world(self, message: Message) -> None:
        if not isinstance(message, World):
            return
        self.monitor.on_world(message)
        if not self._start_games:
            return
        for attention in self.monitor.joint():
            pair = (attention.a, attention.b)
            if message.robot in pair and self._due(pair):
                event: AttentionEvent = {
                    "event": "game",
                    "robots": list(pair),
                    "stamp": time.time(),
                    "objects": [list(p) for p in attention.pairs],
                }
                for game in self._start(pair, attention.pairs):
                    self._emit({**event, **game})

    def _due(self, pair: tuple[str, str]) -> bool:
        """Whether the pair's next games are due now (and then they are taken as started)."""
        now = self._clock()
        with self._lock:
            if now - self._started.get(pair, -math.inf) < self.settings.game_interval:
                return False
            self._started[pair] = now
            return True

    def _on_event(self, event: AttentionEvent) -> None:
        log.info("%s: %s", event["event"], " and ".join(event["robots"]))
        a, b = event["robots"]
        if event["event"] != "joint_attention" or not self._start_games or not self._due((a, b)):
            self._emit(event)
            return
        # The first game rides on the event; the others are events of their own.
        started = self._start((a, b), tuple((p[0], p[1]) for p in event.get("objects", [])))
        for i, game in enumerate(started):
            self._emit({**event, "event": "game", **game} if i else {**event, **game})
        if not started:
            self._emit(event)

    def _start(
        self, pair: tuple[str, str], pairs: tuple[tuple[ObjectId, ObjectId], ...]
    ) -> list[_Started]:
        """Start each of the experiment's games for the two robots of ``pair``, telling each
        its anchors of the context; what was started."""
        a, b = pair
        objects = {a: tuple(p[0] for p in pairs), b: tuple(p[1] for p in pairs)}
        started: list[_Started] = []
        turn = next(self._turn)
        for i, play in enumerate(self.settings.games):
            # Each game's speakers take turns, and a round's games have different speakers.
            speaker, hearer = (a, b) if (turn + i) % 2 == 0 else (b, a)
            game = f"{self.link.name}-{secrets.token_hex(4)}"
            for robot in (speaker, hearer):
                start = Signal(
                    game, self.link.name, robot, "start", speaker, hearer, play, objects[robot]
                )
                self.link.publish("signal", start)
            started.append({"game": game, "speaker": speaker, "hearer": hearer, "play": play})
        return started


class _Started(TypedDict):
    """A game the monitor started (the fields it adds to an event)."""

    game: str
    speaker: str
    hearer: str
    play: str
