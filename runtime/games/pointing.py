"""Language-game scripts as finite-state machines over the peer channels (SPEC §4.7).

The pointing game, the example that exercises perception, kinematics, the peer pose and
messaging end to end:

1. the speaker picks a random object it sees (of its world model, visible in the frame) as topic
   and points at it: it sends the topic's ``(x, y)`` in its own frame on ``/pointing``. A speaker
   that moves its head (gaze) looks at the topic first and points where it sees it then (the
   game fails when it does not see it there within a few frames);
2. the hearer maps the point into its frame, ``v = R(theta_r) (x, y) + (x_r, y_r)`` with its
   estimate of the speaker's pose, with gaze turns its head there and waits until it has seen the
   place, picks the nearest object of its world model (none when that is farther than the gate),
   which may be one it remembers out of sight (the speaker may point where the hearer is not
   looking, or cannot look), and answers with its anchor id and that object's ``(x, y)`` in the
   hearer's frame;
3. the speaker decides whether the hearer chose the same physical object: it maps the hearer's
   ``(x, y)`` back into its own frame with its estimate of the hearer's pose and takes its own
   nearest object there (by the same rule). Same object when that is the topic, or another
   anchor at the topic's place (within the gate of it: :func:`same_place`). The anchor ids
   of two robots never agree (each robot names its anchors), so the position is what is compared;
4. the speaker signals ``success`` or ``failure``; both record the game's result.

Either side without a pose for the other fails the game gracefully: the hearer answers ``null``,
the speaker signals ``failure`` with the reason.

The machines are pure (messages in, messages out); :class:`PointingGames` runs them over a
:class:`~percept.runtime.net.link.Link` as a :class:`~percept.runtime.games.service.GameService`:
only with the robots it is told to play with (the daemon's are the experiment's), with bounded
results and log lines. The looks (:mod:`percept.runtime.games.looking`) happen in the service,
between the machines' steps and never on the network's threads: the speaker's on the thread
that plays the game, the hearer's on a thread of its own (one at a time: a request that comes
while the hearer is turning to another place is answered at once, without a look).
"""

from __future__ import annotations

import itertools
import logging
import math
import random
import secrets
import threading
import time
from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal

from percept.runtime.games.service import GameResult, GameService, Outcome, hear
from percept.runtime.net.link import LinkError
from percept.runtime.net.messages import (
    Message,
    ObjectId,
    PeerPose,
    PointingAnswer,
    PointingRequest,
    Signal,
    World,
)
from percept.runtime.net.peers import to_my_frame
from percept.runtime.net.settings import PeerSettings

if TYPE_CHECKING:
    from percept.runtime.games.looking import Look, Looker
    from percept.runtime.net.link import Link

log = logging.getLogger("percept.games")

WorldSource = Callable[[], list["Located"]]
PoseSource = Callable[[str], PeerPose | None]

UNAMBIGUOUS = 2.0
"""Past the gate, the nearest object is taken within this many gates when the next nearest is
this many times as far (:func:`nearest`)."""


@dataclass(frozen=True)
class Located:
    """An object of a robot's world model at ``(x, y)`` on the ground, in that robot's frame;
    ``visible`` False when it is remembered out of sight."""

    id: ObjectId
    x: float
    y: float
    visible: bool = True


def located(world: World) -> list[Located]:
    """The objects of a world model that have a ground position, seen or remembered."""
    return [
        Located(o.id, *p, visible=o.visible) for o in world.objects if (p := o.position) is not None
    ]


def _only(world: WorldSource, ids: Collection[ObjectId]) -> WorldSource:
    """The objects of ``world`` whose ids are ``ids`` (a context)."""
    context = set(ids)
    return lambda: [o for o in world() if o.id in context]


def _looked(reason: str, look: Look | None) -> str:
    """A failed game's ``reason``, with why the look before it was given up if it was."""
    if look is None or look.seen:
        return reason
    return f"{reason} (the look there was given up: {look.reason})"


def nearest(objects: Iterable[Located], x: float, y: float, gate: float) -> Located | None:
    """The object nearest to ``(x, y)`` when it lies within ``gate`` metres, or within twice
    that and no other place holds an object within twice its distance (:data:`UNAMBIGUOUS`);
    else None.

    A place is off the true object by the speaker's ground error, the error of the peer pose
    that maps it and the hearer's ground error together; the gate holds that sum most of the
    time, not always (the three add up to 5-6 cm now and then in the simulated pointing game
    with turning heads, against 1-2 cm each typically). Past the gate the nearest object is still
    the one meant when nothing else could be: a neighbour at least twice as far is as unlikely
    to be the topic as an object beyond the gate. Objects within the gate of the nearest one
    are at its place (:func:`same_place`), not other candidates."""

    def off(o: Located) -> float:
        return math.hypot(o.x - x, o.y - y)

    ranked = sorted(objects, key=off)
    if not ranked:
        return None
    best = ranked[0]
    if off(best) <= gate:
        return best
    second = next((off(o) for o in ranked[1:] if not same_place(o, best, gate)), math.inf)
    if off(best) <= UNAMBIGUOUS * gate and second >= UNAMBIGUOUS * off(best):
        return best
    return None


def same_place(a: Located, b: Located, gate: float) -> bool:
    """Whether two objects of one world model lie within ``gate`` of each other: one place as
    far as pointing can tell, and one object when the gate is below half the objects' spacing
    (as it should be): two anchors of it, which perception holds now and then after a head
    turn (one for a shaded part)."""
    return math.hypot(a.x - b.x, a.y - b.y) <= gate


class Speaker:
    """The speaker's side of one pointing game: ``ready -> pointing -> done``."""

    def __init__(
        self,
        game: str,
        me: str,
        hearer: str,
        world: WorldSource,
        poses: PoseSource,
        gate: float,
        rng: random.Random,
    ) -> None:
        self.game, self.me, self.hearer = game, me, hearer
        self._world, self._poses, self._gate, self._rng = world, poses, gate, rng
        self.state: Literal["ready", "pointing", "done"] = "ready"
        self.topic: Located | None = None
        self.result: GameResult | None = None

    def start(self) -> list[Message]:
        """Pick the topic and point at it at once."""
        self.choose()
        return self.point()

    def choose(self) -> Located | None:
        """Pick the topic among the objects seen; None when there is none."""
        objects = [o for o in self._world() if o.visible]
        self.topic = self._rng.choice(objects) if objects else None
        return self.topic

    def point(self) -> list[Message]:
        """Point at the topic where the world model has it now (after a look, where it is seen
        from there), or, when its anchor is not seen, at the object seen nearest to where it
        was, within the gate (the anchor may have been made anew while the head turned); the
        game fails when there is no topic or nothing is seen there."""
        if self.topic is None:
            return self._end("failure", None, "the speaker sees no object")
        now = self.seen_topic()
        if now is None:
            return self._end("failure", None, "the speaker does not see its topic")
        self.topic = now
        self.state = "pointing"
        return [PointingRequest(self.game, self.me, self.hearer, now.x, now.y)]

    def seen_topic(self) -> Located | None:
        """The topic as seen now: its anchor, else the object seen nearest to where it was
        (:func:`nearest`); None when there is no topic or nothing is seen there."""
        if self.topic is None:
            return None
        seen = [o for o in self._world() if o.visible]
        now = next((o for o in seen if o.id == self.topic.id), None)
        return now or nearest(seen, self.topic.x, self.topic.y, self._gate)

    def on_answer(self, answer: PointingAnswer) -> list[Message]:
        """The hearer's choice: decide whether it is the topic and signal the outcome."""
        if self.state != "pointing" or answer.game != self.game:
            return []
        if answer.object is None:
            return self._end("failure", None, "the hearer found no object there")
        if answer.x is None or answer.y is None:
            return self._end("failure", answer.object, "the answer has no position to check")
        pose = self._poses(self.hearer)
        if pose is None:
            return self._end(
                "failure", answer.object, "the speaker does not know the hearer's pose"
            )
        x, y = to_my_frame(pose, answer.x, answer.y)
        mine = nearest(self._world(), x, y, self._gate)
        topic = self.topic
        if mine is None or topic is None:
            return self._end("failure", answer.object, "the hearer chose another object")
        if mine.id != topic.id and not same_place(mine, topic, self._gate):
            return self._end("failure", answer.object, "the hearer chose another object")
        return self._end("success", answer.object)

    def on_timeout(self) -> list[Message]:
        """No answer in time."""
        if self.state == "done":
            return []
        return self._end("failure", None, "no answer")

    def _end(self, outcome: Outcome, chosen: ObjectId | None, reason: str = "") -> list[Message]:
        self.state = "done"
        topic = self.topic.id if self.topic else None
        self.result = GameResult(self.game, "speaker", self.hearer, outcome, topic, chosen, reason)
        return [Signal(self.game, self.me, self.hearer, outcome)]


class Hearer:
    """The hearer's side of one pointing game: ``ready -> answered -> done``."""

    def __init__(
        self, game: str, me: str, speaker: str, world: WorldSource, poses: PoseSource, gate: float
    ) -> None:
        self.game, self.me, self.speaker = game, me, speaker
        self._world, self._poses, self._gate = world, poses, gate
        self.state: Literal["ready", "answered", "done"] = "ready"
        self.chosen: ObjectId | None = None
        self.reason = ""
        self.result: GameResult | None = None

    def place(self, request: PointingRequest) -> tuple[float, float] | None:
        """Where the speaker points, in my frame; None without the speaker's pose."""
        pose = self._poses(self.speaker)
        return None if pose is None else to_my_frame(pose, request.x, request.y)

    def on_request(self, request: PointingRequest) -> list[Message]:
        """Interpret the pointing: the nearest object to where the speaker points, or none."""
        if self.state != "ready":
            return []
        self.state = "answered"
        place = self.place(request)
        if place is None:
            self.reason = "the hearer does not know the speaker's pose"
            return [PointingAnswer(self.game, self.me, self.speaker, None)]
        choice = nearest(self._world(), *place, self._gate)
        if choice is None:
            self.reason = "no object near the pointed place"
            return [PointingAnswer(self.game, self.me, self.speaker, None)]
        self.chosen = choice.id
        return [PointingAnswer(self.game, self.me, self.speaker, choice.id, choice.x, choice.y)]

    def on_signal(self, signal: Signal) -> list[Message]:
        """The speaker's verdict ends the game."""
        if self.state == "done" or signal.signal not in ("success", "failure"):
            return []
        self.state = "done"
        outcome: Outcome = "success" if signal.signal == "success" else "failure"
        self.result = GameResult(
            self.game, "hearer", self.speaker, outcome, None, self.chosen, self.reason
        )
        return []


class PointingGames(GameService):
    """Plays pointing games for robot ``me`` over ``link``: as speaker when :meth:`play` is
    called (or the joint-attention monitor signals ``start`` with ``me`` as speaker), as hearer
    whenever another robot points at it. ``world`` gives my objects now, ``poses`` my estimate
    of a peer's pose (e.g. :meth:`percept.runtime.net.peers.PeerTracker.pose`). ``players``: the
    robots games are played with (None: any); pointing and verdicts from others, and start signals
    naming another hearer, are ignored and counted by sender (:attr:`ignored`). ``looker``: the
    robot's looks when it moves its head (None: it does not; the daemon sets it once gaze is
    open), see the module text."""

    kind = "pointing"

    def __init__(
        self,
        link: Link,
        world: WorldSource,
        poses: PoseSource,
        settings: PeerSettings | None = None,
        rng: random.Random | None = None,
        players: Collection[str] | None = None,
        looker: Looker | None = None,
    ) -> None:
        super().__init__(link, players, (settings or PeerSettings()).monitor)
        self.settings = settings or PeerSettings()
        self.looker = looker
        self._world, self._poses = world, poses
        self._turning = False  # a hearer's look is under way
        self._rng = rng or random.Random()
        self._count = itertools.count(1)
        self._speaking: dict[str, tuple[Speaker, threading.Event]] = {}
        self._hearing: dict[str, tuple[float, Hearer]] = {}
        link.subscribe("pointing", self._on_pointing)
        link.subscribe("signal", self._on_verdict)

    def play(
        self, hearer: str, game: str | None = None, objects: Collection[ObjectId] | None = None
    ) -> GameResult:
        """Play one game as speaker with ``hearer`` about one of ``objects`` of my world model
        (None: any); blocks until it ends (at most the answer timeout; with a looker, my look
        and, for the hearer's, twice the longest look more)."""
        game = game or f"{self.me}-{next(self._count)}-{secrets.token_hex(3)}"
        world = self._world if objects is None else _only(self._world, objects)
        gate = self.settings.pointing_gate
        looker = self.looker
        speaker = Speaker(game, self.me, hearer, world, self._poses, gate, self._rng)
        topic = speaker.choose()
        look = looker.look(topic.x, topic.y) if looker is not None and topic is not None else None
        if looker is not None and look is not None and look.seen:
            # Right after the turn the topic's anchor may miss a frame or two.
            looker.watch(lambda: speaker.seen_topic() is not None)
        answered = threading.Event()
        with self._lock:
            self._speaking[game] = (speaker, answered)
            out = speaker.point()
        if speaker.result is not None:  # it failed before pointing
            speaker.result = replace(speaker.result, reason=_looked(speaker.result.reason, look))
        self._send(out)
        wait = self.settings.answer_timeout + (2 * looker.longest() if looker else 0.0)
        if speaker.state != "done" and not answered.wait(wait):
            with self._lock:
                out = speaker.on_timeout()
            self._send(out)
        with self._lock:
            self._speaking.pop(game, None)
        if looker is not None:
            looker.back()
        assert speaker.result is not None
        return self._finish(speaker.result)

    def _send(self, messages: list[Message]) -> None:
        for m in messages:
            self.link.publish("pointing" if not isinstance(m, Signal) else "signal", m)

    def _on_pointing(self, message: Message) -> None:
        if not isinstance(message, PointingAnswer | PointingRequest) or message.to != self.me:
            return
        if not self._plays_with(message.sender, message.sender):
            return
        if isinstance(message, PointingAnswer):
            with self._lock:
                entry = self._speaking.get(message.game)
                out = entry[0].on_answer(message) if entry else []
            self._send(out)
            if entry and entry[0].state == "done":
                entry[1].set()
        else:
            self._on_request(message)

    def _on_request(self, request: PointingRequest) -> None:
        hearer = Hearer(
            request.game,
            self.me,
            request.sender,
            self._world,
            self._poses,
            self.settings.pointing_gate,
        )
        age = 10 * self.settings.answer_timeout
        looker = self.looker
        with self._lock:
            hear(self._hearing, request.game, hearer, time.monotonic(), age)
            turning = looker is not None and not self._turning
            self._turning = self._turning or turning
        if looker is None or not turning:
            self._send(hearer.on_request(request))
            return
        threading.Thread(
            target=self._look_and_answer,
            args=(looker, hearer, request),
            name=f"hear {request.game}",
            daemon=True,
        ).start()

    def _look_and_answer(self, looker: Looker, hearer: Hearer, request: PointingRequest) -> None:
        """The hearer turns to where the speaker points, then answers (on a thread of its own)."""
        try:
            place = hearer.place(request)
            look = looker.look(*place) if place is not None else None
            out = hearer.on_request(request)
            if hearer.reason:  # it found nothing
                hearer.reason = _looked(hearer.reason, look)
            self._send(out)
        except LinkError as err:  # the link closed under the game: this process is ending
            log.info("%s: game %s ended with the link: %s", self.me, request.game, err)
            return
        finally:
            with self._lock:
                self._turning = False
        looker.back()

    def _on_verdict(self, message: Message) -> None:
        """A player's verdict ends a game I hear (start signals are the service's)."""
        if not isinstance(message, Signal) or message.to != self.me or message.signal == "start":
            return
        if not self._plays_with(message.sender, message.sender):
            return
        with self._lock:
            entry = self._hearing.pop(message.game, None)
        if entry is not None:
            entry[1].on_signal(message)
            if entry[1].result is not None:
                self._finish(entry[1].result)
