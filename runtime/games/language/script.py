"""Game scripts: a language game as a finite-state machine per participant (SPEC §4.7).

A researcher's own game is a subclass of :class:`Script` per role. A script is in one state at a
time; each message that reaches it is an :class:`Event` of some ``kind`` (``start``,
``utterance``, ``guess``, ``feedback``, ``signal``, ``pointing``, ``timeout`` or one of the
researcher's own);
the method decorated ``@on(state, kind)`` handles it, sends messages through ``send`` (channel
kind and JSON-able payload) and returns the next state. Events a state has no handler for are
counted in :attr:`Script.ignored` and change nothing, so a stray or repeated message cannot
derail a game. What a script knows of the world comes from callables it is given: the robot's
objects now and its estimate of the peer's pose, as the daemon has them.

:class:`GuessingSpeaker` and :class:`GuessingHearer` are the guessing game
(:mod:`percept.runtime.games.language.guessing`) as scripts: the same rules, split at the messages::

    speaker  ready --start--> (utterance) heard --guess--> (feedback, pointing on failure) done
    hearer   ready --utterance--> (guess) guessed --feedback--> done

:class:`LocalChannel` passes the messages of two scripts to each other in one process (tests, and
trying a game on recorded scenes); the daemons carry the same payloads over Zenoh, a kind being
the topic and its payload the message (``percept.utterance/1``, ``percept.guess/1``,
``percept.feedback/1``; :mod:`percept.runtime.games.language.live`). The pointing game of
:mod:`percept.runtime.games.pointing` has the same shape (request, answer, signal).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from percept.runtime.games.language.agents import Agent
from percept.runtime.games.language.categories import Category
from percept.runtime.games.language.dataset.records import to_mine
from percept.runtime.games.language.guessing import GuessingGame
from percept.runtime.net.codec import JSON

Payload = Mapping[str, JSON]
Send = Callable[[str, Payload], None]


@dataclass(frozen=True)
class Event:
    """A message (or a start or timeout) reaching a script: its ``kind`` and ``data``."""

    kind: str
    data: Payload = field(default_factory=dict)


@dataclass(frozen=True)
class Thing:
    """An object of a robot's world model as a script sees it: anchor id, ground position in
    the robot's frame, and its values on the game's channels (NaN: unknown)."""

    id: str
    x: float
    y: float
    values: tuple[float, ...]


@dataclass(frozen=True)
class PeerPose2:
    """Where the peer stands in my ground frame."""

    x: float
    y: float
    theta: float

    def to_mine(self, x: float, y: float) -> tuple[float, float]:
        """A point of the peer's frame in mine: ``R(theta) (x, y) + (x_r, y_r)``."""
        return to_mine((self.x, self.y, self.theta), x, y)


World = Callable[[], Sequence[Thing]]
PeerPose = Callable[[], PeerPose2 | None]


def on(state: str, kind: str) -> Callable[[Callable[..., str]], Callable[..., str]]:
    """Mark a method as the handler of events of ``kind`` in ``state``; it returns the next
    state."""

    def mark(method: Callable[..., str]) -> Callable[..., str]:
        method._handles = (state, kind)  # type: ignore[attr-defined]
        return method

    return mark


class Script:
    """One participant of one game: state, handlers, and the ways out (``send``)."""

    initial: ClassVar[str] = "ready"
    final: ClassVar[frozenset[str]] = frozenset({"done"})
    _handlers: ClassVar[dict[tuple[str, str], str]]

    def __init_subclass__(cls) -> None:
        super().__init_subclass__()
        cls._handlers = {}
        for klass in reversed(cls.__mro__):
            for name, value in vars(klass).items():
                if hasattr(value, "_handles"):
                    cls._handlers[value._handles] = name

    def __init__(self, game: str, me: str, peer: str, send: Send) -> None:
        self.game, self.me, self.peer = game, me, peer
        self._send = send
        self.state = self.initial
        self.ignored = 0
        self.success: bool | None = None

    @property
    def done(self) -> bool:
        return self.state in self.final

    def send(self, kind: str, **data: JSON) -> None:
        """Send a message of ``kind`` to the peer, addressed as the others are."""
        self._send(kind, {"game": self.game, "from": self.me, "to": self.peer, **data})

    def handle(self, event: Event) -> None:
        """Run the handler of ``event`` in the current state, or count it as ignored."""
        name = self._handlers.get((self.state, event.kind))
        if name is None or event.data.get("game", self.game) != self.game:
            self.ignored += 1
            return
        self.state = getattr(self, name)(event)


def nearest(things: Sequence[Thing], x: float, y: float, gate: float) -> int | None:
    """Index of the thing nearest to ``(x, y)``, or None when none is within ``gate``."""
    if not things:
        return None
    d = [math.hypot(t.x - x, t.y - y) for t in things]
    k = int(np.argmin(d))
    return k if d[k] <= gate else None


def _number(value: JSON) -> float:
    """A coordinate of a message; the scripts send them as numbers."""
    if isinstance(value, int | float):
        return float(value)
    raise TypeError(f"expected a number, got {value!r}")


def _values(things: Sequence[Thing]) -> np.ndarray:
    return np.array([t.values for t in things], dtype=float)


class _Guessing(Script):
    """What both sides of a guessing game hold: the rules, the agent, the world, the peer's
    pose and the pointing gate."""

    def __init__(
        self,
        game: str,
        me: str,
        peer: str,
        send: Send,
        rules: GuessingGame,
        agent: Agent[Category],
        world: World,
        peer_pose: PeerPose,
        gate: float,
    ) -> None:
        super().__init__(game, me, peer, send)
        self.rules, self.agent, self.world, self.peer_pose = rules, agent, world, peer_pose
        self.gate = gate
        self.things: Sequence[Thing] = ()


class GuessingSpeaker(_Guessing):
    """The speaker's side of a guessing game (see the module text); ``rng`` picks the topic
    and makes new words."""

    def __init__(
        self,
        game: str,
        me: str,
        peer: str,
        send: Send,
        rules: GuessingGame,
        agent: Agent[Category],
        world: World,
        peer_pose: PeerPose,
        gate: float,
        *,
        rng: np.random.Generator,
    ) -> None:
        super().__init__(game, me, peer, send, rules, agent, world, peer_pose, gate)
        self.rng = rng
        self.topic = -1
        self.said: tuple[str, Category] | None = None
        self.reason = ""

    @on("ready", "start")
    def start(self, event: Event) -> str:
        self.things = self.world()
        if not self.things:
            return self._end(False, "nothing in view")
        self.topic = int(self.rng.integers(len(self.things)))
        self.said = self.rules.speak(self.agent, _values(self.things), self.topic, self.rng)
        if self.said is None:
            return self._end(False, "no category tells the topic apart")
        self.send("utterance", word=self.said[0])
        return "heard"

    @on("heard", "guess")
    def guess(self, event: Event) -> str:
        """The hearer points at what it understood: is it the topic?"""
        assert self.said is not None
        pose, x, y = self.peer_pose(), event.data.get("x"), event.data.get("y")
        chosen = None
        if pose is not None and x is not None and y is not None:
            chosen = nearest(self.things, *pose.to_mine(_number(x), _number(y)), self.gate)
        success = chosen == self.topic
        word, category = self.said
        values = _values(self.things)
        self.rules.learn(self.agent, word, category, values, self.topic, success, hearer=False)
        if success:
            self.send("feedback", signal="success")
        else:
            topic = self.things[self.topic]
            self.send("feedback", signal="failure", x=topic.x, y=topic.y)
        return self._end(success)

    @on("heard", "timeout")
    def timeout(self, event: Event) -> str:
        return self._end(False, "no answer")

    def _end(self, success: bool, reason: str = "") -> str:
        self.success, self.reason = success, reason
        return "done"


class GuessingHearer(_Guessing):
    """The hearer's side of a guessing game (see the module text)."""

    # What it heard, the category it took the word for and the object it pointed at.
    word: str = ""
    meaning: Category | None = None
    pick: int | None = None

    @on("ready", "utterance")
    def utterance(self, event: Event) -> str:
        """Interpret the word and point at the object it means (or at nothing)."""
        self.things = self.world()
        self.word = str(event.data.get("word", ""))
        if self.things:
            self.pick, self.meaning = self.rules.interpret(
                self.agent, self.word, _values(self.things)
            )
        if self.pick is None:
            self.send("guess", object=None)
        else:
            chosen = self.things[self.pick]
            self.send("guess", object=chosen.id, x=chosen.x, y=chosen.y)
        return "guessed"

    @on("guessed", "feedback")
    def feedback(self, event: Event) -> str:
        """Success: the topic is the object this hearer pointed at. Failure: the speaker points
        at the topic; learn the word for it (when it can be found)."""
        if event.data.get("signal") == "success" and self.pick is not None:
            values = _values(self.things)
            self.rules.learn(self.agent, self.word, self.meaning, values, self.pick, True, True)
            self.success = True
            return "done"
        self.success = False
        pose, x, y = self.peer_pose(), event.data.get("x"), event.data.get("y")
        if pose is None or not self.things or x is None or y is None:
            return "done"
        topic = nearest(self.things, *pose.to_mine(_number(x), _number(y)), self.gate)
        if topic is not None:
            values = _values(self.things)
            self.rules.learn(self.agent, self.word, self.meaning, values, topic, False, True)
        return "done"


class LocalChannel:
    """Messages between scripts in one process: :meth:`send` is every script's way out, and
    :meth:`run` delivers them to their addressees."""

    def __init__(self) -> None:
        self.queue: deque[tuple[str, Payload]] = deque()

    def send(self, kind: str, payload: Payload) -> None:
        self.queue.append((kind, payload))

    def run(self, speaker: Script, hearer: Script) -> None:
        """Start the speaker, then deliver each message until none is left."""
        scripts = {speaker.me: speaker, hearer.me: hearer}
        speaker.handle(Event("start", {"game": speaker.game}))
        while self.queue:
            kind, payload = self.queue.popleft()
            scripts[str(payload["to"])].handle(Event(kind, payload))
