"""The guessing game between daemons over Zenoh: one agent per robot, learning across games.

:class:`GuessingGames` runs the guessing game's scripts (:mod:`.script`) over a
:class:`~percept.runtime.net.link.Link`, each kind of script event being a topic and its payload
that topic's message: the speaker's ``percept.utterance/1`` (the word), the hearer's
``percept.guess/1`` (it points at the object it takes the word to mean) and the speaker's
``percept.feedback/1`` (success, or failure and a pointing at the topic). They are checked like
every other message: a malformed one is rejected and counted by the link and never reaches a
game. A game starts when the joint-attention monitor signals ``start`` with ``play`` guessing,
naming this robot as speaker; the signal's ``objects`` are the context, the anchors both robots
attend to, and the hearer gets its own in its start signal (when its signal comes after the
utterance, the hearer's whole world model is its context). The robot's agent (lexicon and
categories) is the same in every game, as speaker and as hearer, and learns across games.

The game's channels are the scaled features both robots can compare
(:data:`~percept.runtime.games.language.dataset.contexts.SHARED_CHANNELS`); an object's position
is where the two robots point.
"""

from __future__ import annotations

import itertools
import logging
import math
import secrets
import threading
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from percept.runtime.games.language.dataset.contexts import SHARED_CHANNELS
from percept.runtime.games.language.guessing import GuessingGame, GuessingSettings
from percept.runtime.games.language.script import (
    Event,
    GuessingHearer,
    GuessingSpeaker,
    Payload,
    PeerPose2,
    Script,
    Thing,
)
from percept.runtime.games.service import HEARING_KEPT, GameResult, GameService, Outcome, hear
from percept.runtime.net.messages import (
    Feedback,
    Guess,
    Message,
    MessageError,
    ObjectId,
    PeerPose,
    Signal,
    Utterance,
    World,
)
from percept.runtime.net.settings import PeerSettings

if TYPE_CHECKING:
    from percept.runtime.net.link import Link

log = logging.getLogger("percept.games")

_KINDS: dict[type, str] = {Utterance: "utterance", Guess: "guess", Feedback: "feedback"}

WORDS_KEPT = 1024
"""Word forms a robot's agent holds at most: a new one pushes out the weakest (a player making
up a word per game cannot grow the lexicon without end; the experiment's vocabulary is tens)."""
CATEGORIES_KEPT = 1024
"""Categories a robot's agent makes at most: past it, a topic no category tells apart makes none
and its game fails, as when no channel tells it apart."""

ThingSource = Callable[[], Sequence[Thing]]
PoseSource = Callable[[str], PeerPose | None]


def things(world: World | None, channels: Sequence[str] = SHARED_CHANNELS) -> list[Thing]:
    """The objects of a world model that have a ground position, with their scaled values on
    ``channels`` (NaN where unknown)."""
    if world is None:
        return []
    out = []
    for o in world.objects:
        where = o.position
        if where is not None:
            values = tuple(math.nan if (v := o.scaled.get(c)) is None else v for c in channels)
            out.append(Thing(str(o.id), *where, values))
    return out


@dataclass
class _Speaking:
    """A game this robot speaks in: its script, set when it ends, and what the hearer chose."""

    script: GuessingSpeaker
    ended: threading.Event = field(default_factory=threading.Event)
    chosen: ObjectId | None = None


class GuessingGames(GameService):
    """Plays guessing games for robot ``link.name``: as speaker when :meth:`play` is called (or
    the monitor signals ``start`` for a guessing game with this robot as speaker), as hearer
    whenever a player speaks to it. ``things`` gives my objects now (:func:`things` of the
    latest world model), ``poses`` my estimate of a peer's pose; ``players`` as for every
    :class:`~percept.runtime.games.service.GameService`."""

    kind = "guessing"

    def __init__(
        self,
        link: Link,
        things: ThingSource,
        poses: PoseSource,
        settings: PeerSettings | None = None,
        rng: np.random.Generator | None = None,
        players: Collection[str] | None = None,
        rules: GuessingGame | None = None,
    ) -> None:
        super().__init__(link, players, (settings or PeerSettings()).monitor)
        self.settings = settings or PeerSettings()
        bounds = GuessingSettings(words=WORDS_KEPT, most_categories=CATEGORIES_KEPT)
        self.rules = rules or GuessingGame(len(SHARED_CHANNELS), bounds)
        self.agent = self.rules.new_agent(0)
        self._things, self._poses = things, poses
        self._rng = rng or np.random.default_rng()
        self._count = itertools.count(1)
        self._speaking: dict[str, _Speaking] = {}
        self._hearing: dict[str, tuple[float, GuessingHearer]] = {}
        self._contexts: dict[str, frozenset[str]] = {}  # as hearer: my anchors, by game
        self._out: list[tuple[str, Payload]] = []  # what the scripts said under the lock
        self.unsent = 0  # own messages that failed their check (a bug; logged)
        for topic in _KINDS.values():
            link.subscribe(topic, self._on_message)
        link.subscribe("signal", self._on_hearer_start)

    @property
    def lexicon_size(self) -> int:
        return len(self.agent.lexicon)

    @property
    def categories(self) -> int:
        return 0 if self.agent.categories is None else len(self.agent.categories)

    def play(
        self, hearer: str, game: str | None = None, objects: Collection[ObjectId] | None = None
    ) -> GameResult:
        """Play one game as speaker with ``hearer`` about ``objects`` (None: every object I
        see); blocks until it ends (at most the answer timeout)."""
        game = game or f"{self.me}-{next(self._count)}-{secrets.token_hex(3)}"
        script = GuessingSpeaker(
            game,
            self.me,
            hearer,
            self._say,
            self.rules,
            self.agent,
            self._view(objects),
            self._pose_of(hearer),
            self.settings.pointing_gate,
            rng=self._rng,
        )
        speaking = _Speaking(script)
        with self._lock:
            self._speaking[game] = speaking
        self._run(script, Event("start", {"game": game}))
        if not script.done and not speaking.ended.wait(self.settings.answer_timeout):
            self._run(script, Event("timeout", {"game": game}))
        with self._lock:
            self._speaking.pop(game, None)
        success = bool(script.success)
        reason = script.reason
        if not success and not reason:
            reason = (
                "the hearer knows no meaning of the word there"
                if speaking.chosen is None
                else "the hearer took the word for another object"
            )
        topic = script.things[script.topic].id if script.topic >= 0 else None
        outcome: Outcome = "success" if success else "failure"
        return self._finish(
            GameResult(game, "speaker", hearer, outcome, topic, speaking.chosen, reason)
        )

    # -- the scripts' ways in and out -------------------------------------------------------------

    def _view(self, objects: Collection[ObjectId] | None) -> ThingSource:
        """My objects, only those of the context when there is one."""
        if objects is None:
            return self._things
        ids = frozenset(str(i) for i in objects)
        return lambda: [t for t in self._things() if t.id in ids]

    def _pose_of(self, peer: str) -> Callable[[], PeerPose2 | None]:
        def pose() -> PeerPose2 | None:
            p = self._poses(peer)
            return None if p is None else PeerPose2(p.x, p.y, p.theta)

        return pose

    def _say(self, kind: str, payload: Payload) -> None:
        self._out.append((kind, payload))  # under the lock: in a script's handler

    def _run(self, script: Script, event: Event) -> None:
        """Let ``script`` handle ``event`` (under the lock: the agent is every game's), then
        send what it said."""
        with self._lock:
            script.handle(event)
            out, self._out = self._out, []
        for kind, payload in out:
            try:
                self.link.publish(kind, payload)
            except MessageError as err:  # a bug of ours: the game goes on without it
                self.unsent += 1
                log.error("%s: own %s message not sent, it fails the check: %s", self.me, kind, err)

    def _on_hearer_start(self, message: Message) -> None:
        """The monitor's start naming me as hearer: keep my context for the utterance."""
        if not isinstance(message, Signal) or message.to != self.me or message.signal != "start":
            return
        if message.play != self.kind or message.hearer != self.me or message.objects is None:
            return
        if not self.starts_from(message.sender):
            return
        if not self._plays_with(message.speaker, message.sender):
            return
        with self._lock:
            while len(self._contexts) >= HEARING_KEPT:
                del self._contexts[next(iter(self._contexts))]
            self._contexts[message.game] = frozenset(str(i) for i in message.objects)

    def _on_message(self, message: Message) -> None:
        if not isinstance(message, Utterance | Guess | Feedback) or message.to != self.me:
            return
        if not self._plays_with(message.sender, message.sender):
            return
        event = Event(_KINDS[type(message)], message.to_json())
        if isinstance(message, Utterance):
            self._hear(message, event)
        elif isinstance(message, Guess):
            with self._lock:
                speaking = self._speaking.get(message.game)
            if speaking is None or speaking.script.peer != message.sender:
                return
            speaking.chosen = message.object
            self._run(speaking.script, event)
            if speaking.script.done:
                speaking.ended.set()
        else:
            with self._lock:
                entry = self._hearing.get(message.game)
            if entry is None or entry[1].peer != message.sender:
                return
            hearer = entry[1]
            self._run(hearer, event)
            if hearer.done:
                with self._lock:
                    self._hearing.pop(message.game, None)
                self._finish(self._heard(hearer))

    def _hear(self, utterance: Utterance, event: Event) -> None:
        with self._lock:
            context = self._contexts.pop(utterance.game, None)
        hearer = GuessingHearer(
            utterance.game,
            self.me,
            utterance.sender,
            self._say,
            self.rules,
            self.agent,
            self._view(context),
            self._pose_of(utterance.sender),
            self.settings.pointing_gate,
        )
        age = 10 * self.settings.answer_timeout
        with self._lock:
            hear(self._hearing, utterance.game, hearer, time.monotonic(), age)
        self._run(hearer, event)

    @staticmethod
    def _heard(hearer: GuessingHearer) -> GameResult:
        chosen = hearer.things[hearer.pick].id if hearer.pick is not None else None
        reason = ""
        if not hearer.success:
            reason = "knew no meaning of the word" if chosen is None else "took another object"
        outcome: Outcome = "success" if hearer.success else "failure"
        return GameResult(hearer.game, "hearer", hearer.peer, outcome, None, chosen, reason)
