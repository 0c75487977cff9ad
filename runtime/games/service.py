"""What every game a daemon plays over the network shares: whom it plays with, the games it is
asked to start, and the record of how they ended.

A :class:`GameService` plays one kind of game (``pointing``, ``guessing``) for robot ``me`` over
a :class:`~percept.runtime.net.link.Link`. Anyone who reaches the network can send messages, so
it plays only with its ``players`` (the experiment's robots): a message from anyone else, a start
signal sent by anyone but the ``monitor`` or a player, or one naming another hearer, costs a
count by sender (:attr:`GameService.ignored`, bounded whatever names senders make up) and one log
line. (The link has already rejected every message whose sender is not the robot of the key it
came on.) The joint-attention monitor's ``start`` signal for this kind of game, naming ``me`` as
speaker, plays one game on a thread of its own, one at a time: a flood of starts is not a thread
each. Results are kept in a bounded window, the counts cover every game, and the log lines about
games are bounded too.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter, deque
from collections.abc import Collection
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Literal, TypeVar

from percept.runtime.incidents import LogLimit
from percept.runtime.net.link import LinkError
from percept.runtime.net.messages import Message, ObjectId, Signal

if TYPE_CHECKING:
    from percept.runtime.net.link import Link

log = logging.getLogger("percept.games")

RESULTS_KEPT = 256  # the latest game results kept (the counts cover every game)
HEARING_KEPT = 64  # games heard at once at most (a speaker that never ends one is forgotten)
_STRANGERS_KEPT = 64  # senders outside the players whose ignored messages are counted

Outcome = Literal["success", "failure"]


H = TypeVar("H")


def hear(hearing: dict[str, tuple[float, H]], game: str, hearer: H, now: float, age: float) -> None:
    """Add ``game``'s hearer to the games heard, first forgetting those begun more than ``age``
    seconds ago (their speaker never ended them) and the oldest beyond :data:`HEARING_KEPT`: a
    flood of games begun must not grow the table without end."""
    for other, (began, _) in list(hearing.items()):
        if now - began > age:
            del hearing[other]
    while len(hearing) >= HEARING_KEPT:
        del hearing[next(iter(hearing))]
    hearing[game] = (now, hearer)


@dataclass(frozen=True)
class GameResult:
    """How one game ended for one participant."""

    game: str
    role: Literal["speaker", "hearer"]
    peer: str
    outcome: Outcome
    topic: ObjectId | None = None
    chosen: ObjectId | None = None
    reason: str = ""


class GameService:
    """One kind of game played by robot ``link.name`` with ``players`` (None: anyone); see the
    module text. A subclass plays as speaker in :meth:`play`."""

    kind: ClassVar[str]  # the game a start signal's ``play`` names (null names pointing)

    def __init__(
        self, link: Link, players: Collection[str] | None = None, monitor: str = "monitor"
    ) -> None:
        self.link, self.me = link, link.name
        self.players = None if players is None else frozenset(players) - {self.me}
        self.monitor = monitor
        self._started = False  # a game asked for by a start signal is being played
        self._lock = threading.Lock()
        self.results: deque[GameResult] = deque(maxlen=RESULTS_KEPT)
        self.played = self.won = self.as_speaker = 0
        self.ignored: Counter[str] = Counter()
        self._log_limit = LogLimit(most=20, window=10.0)
        link.subscribe("signal", self._on_signal)

    def play(
        self, hearer: str, game: str | None = None, objects: Collection[ObjectId] | None = None
    ) -> GameResult:
        """Play one game as speaker with ``hearer`` about ``objects`` of my world model (None:
        all of it); blocks until it ends."""
        raise NotImplementedError

    def _play_started(self, hearer: str, game: str, objects: Collection[ObjectId] | None) -> None:
        try:
            self.play(hearer, game, objects)
        except LinkError as err:  # the link closed under the game: this process is ending
            log.info("%s: game %s ended with the link: %s", self.me, game, err)
        finally:
            with self._lock:
                self._started = False

    def _finish(self, result: GameResult) -> GameResult:
        with self._lock:
            self.results.append(result)
            self.played += 1
            self.won += result.outcome == "success"
            self.as_speaker += result.role == "speaker"
            logged = self._log_limit.allow(time.monotonic())
            held = self._log_limit.take_held() if logged else 0
        if logged:
            log.info(
                "%s: %s game %s as %s with %s: %s%s%s",
                self.me,
                self.kind,
                result.game,
                result.role,
                result.peer,
                result.outcome,
                f" ({result.reason})" if result.reason else "",
                f"; {held} games before it not logged" if held else "",
            )
        return result

    def _plays_with(self, robot: str | None, sender: str) -> bool:
        """Whether ``robot`` is one of the players; if not, the message from ``sender`` is
        counted as ignored (the counts stay bounded whatever names senders make up)."""
        if self.players is None or robot in self.players:
            return True
        with self._lock:
            if sender not in self.ignored and len(self.ignored) >= _STRANGERS_KEPT:
                self.ignored = Counter(dict(self.ignored.most_common(_STRANGERS_KEPT // 2)))
            self.ignored[sender] += 1
            first = self.ignored[sender] == 1 and self._log_limit.allow(time.monotonic())
        if first:
            log.warning(
                "%s: ignoring %s games with %s (from %s): not one of the players %s",
                self.me,
                self.kind,
                robot,
                sender,
                ", ".join(sorted(self.players)) or "(none)",
            )
        return False

    def starts_from(self, sender: str) -> bool:
        """Whether a start signal from ``sender`` is heeded: the monitor's or a player's (else
        it is counted as ignored)."""
        return sender == self.monitor or self._plays_with(sender, sender)

    def _on_signal(self, message: Message) -> None:
        if not isinstance(message, Signal) or message.to != self.me or message.signal != "start":
            return
        if (message.play or "pointing") != self.kind:
            return
        if message.speaker != self.me or not message.hearer:
            return
        # The monitor sends start, and the hearer it names must be a player.
        if not self.starts_from(message.sender):
            return
        if not self._plays_with(message.hearer, message.sender):
            return
        with self._lock:
            busy, self._started = self._started, True
        if busy:
            log.debug("%s: start of game %s ignored: one is under way", self.me, message.game)
            return
        threading.Thread(
            target=self._play_started,
            args=(message.hearer, message.game, message.objects),
            name=f"game {message.game}",
            daemon=True,
        ).start()
