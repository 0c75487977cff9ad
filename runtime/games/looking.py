"""Looking during a game: the head turned to a place on the ground until perception has seen it.

A game that looks (the speaker at its topic before pointing, the hearer where the speaker
points) asks its robot's :class:`Looker` to face a point on the ground of the robot's frame. The
gaze turns the head there (:meth:`~percept.runtime.daemon.gaze.Gaze.look_at`); the looker waits
until the head has settled, at most the time the servo speed allows plus :data:`SETTLE_MARGIN`,
and then until perception has finished :data:`SEEN_FRAMES` frames taken after that, at most
:data:`SEEN_WAIT` seconds, so that the world model holds what is at that place: an object seen
again in view, or one seen there for the first time. The frames are counted by when they were
taken, not when they were finished: on a busy machine perception finishes frames taken while
the head was still turning well after it settled (its queue, dropped frames), and the ground
positions of those frames are off by the head's motion during their exposure and by the age
of the joint reading they were paired with. So a look lasts as many frames, not as many
seconds, whatever the load. After it a game may wait a few frames more for what it looked at
(:meth:`Looker.watch`): an anchor is now and then missing from a frame or two after a turn.

Gaze stopped by a fault on the way (a stale joint: a late servo reply, on a busy machine) is
engaged again by the next look, so the look is tried again after a short pause as long as it may
last. The robot has one head, so one look at a time: a game that finds the head busy waits for
it, at most as long as one look may take (:meth:`Looker.longest`). A look that cannot be made
(the place outside the head's range, gaze stopped on a fault, the head not settled in time, the
head busy) is reported in a :class:`Look` and logged; the game goes on with what the robot sees
or remembers. When its part of the game is over the robot looks back (:meth:`Looker.back`) to
where its head was when the games began to look, so that the landmark boxes stay in view.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from percept.kinematics.gaze import Unreachable
from percept.runtime.daemon.gaze import Fixation

if TYPE_CHECKING:
    from percept.runtime.daemon.gaze import Gaze

log = logging.getLogger("percept.games")

SETTLE_MARGIN = 1.0
"""Seconds a head may take to settle beyond what the gaze speed allows (as a gaze fixation)."""
SEEN_FRAMES = 4
"""Frames taken after the head settled that perception finishes before the place counts as
seen (the anchors' filters take a few frames to settle on the view from there)."""
SEEN_WAIT = 3.0
"""Seconds to wait for those frames at most (a camera that stalls must not hold up a game)."""
RETRY_PAUSE = 0.3
"""Seconds before a look that gaze gave up on (a fault) is tried again."""


@dataclass(frozen=True)
class Look:
    """How one look went: whether the head faced the place and perception saw it, and why
    not."""

    seen: bool
    reason: str = ""


Frames = Callable[[], tuple[int, float]]
"""The number of frames perception has finished (it only grows) and the time the last of them
was taken (``time.monotonic``)."""


class Looker:
    """Looks at ground points for the games of one robot over its ``gaze``; ``frames`` tells how
    far perception is (:data:`Frames`). ``stop`` ends a wait early (the daemon stopping)."""

    def __init__(self, gaze: Gaze, frames: Frames, stop: threading.Event | None = None) -> None:
        self._gaze = gaze
        self._frames = frames
        self._stop = stop or threading.Event()
        self._head = threading.Lock()  # one look at a time
        here = sample.angles if (sample := gaze.head.latest()) else {}
        self._home = {n: here[n] for n in gaze.limits if n in here}

    def longest(self) -> float:
        """Seconds one look may take at most: across the widest gaze joint's whole range at
        the gaze speed, the settling margin and the wait for frames."""
        widest = max(lim.max - lim.min for lim in self._gaze.limits.values())
        return widest / self._gaze.settings.max_speed + SETTLE_MARGIN + SEEN_WAIT

    def look(self, x: float, y: float, z: float = 0.0) -> Look:
        """Face ``(x, y, z)`` (this robot's ground frame, metres), wait until the head settled
        and perception saw it; blocks for at most twice :meth:`longest` (waiting for the head,
        then looking)."""
        if not self._head.acquire(timeout=self.longest()):
            return self._given_up((x, y, z), "the head is busy with another look")
        try:
            return self._look((x, y, z))
        finally:
            self._head.release()

    def _look(self, target: tuple[float, float, float]) -> Look:
        why = self._face(target)
        if why is not None:
            return self._given_up(target, why)
        settled = time.monotonic()
        end = settled + SEEN_WAIT
        first: int | None = None  # the count once the first frame taken after settling is in
        while True:
            count, taken = self._frames()
            if first is None and taken >= settled:
                first = count
            if first is not None and count - first + 1 >= SEEN_FRAMES:
                return Look(True)
            if time.monotonic() >= end or self._stop.wait(0.01):
                why = f"no {SEEN_FRAMES} frames taken after the head settled in {SEEN_WAIT} s"
                return self._given_up(target, why)

    def watch(self, until: Callable[[], bool]) -> bool:
        """Whether ``until()`` holds now or in one of the next :data:`SEEN_FRAMES` frames
        perception finishes (waited for at most :data:`SEEN_WAIT` seconds): after a look, what
        the robot looked at may be missing from a frame or two while its anchor is associated
        again (seen in the frames before, remembered in this one)."""
        last, _ = self._frames()
        end, frames = time.monotonic() + SEEN_WAIT, last + SEEN_FRAMES
        while not until():
            while (count := self._frames()[0]) == last:  # the next frame's world model
                if time.monotonic() >= end or self._stop.wait(0.01):
                    return until()
            if count >= frames:
                return until()
            last = count
        return True

    def _face(self, target: tuple[float, float, float]) -> str | None:
        """Turn the head to ``target`` until it settles; None then, else why it cannot."""
        gaze = self._gaze

        def move(left: float) -> str | None:
            goals = gaze.look_at(*target)
            allowed = gaze.travel_time(goals) + SETTLE_MARGIN  # from where the head is now
            if gaze.wait_settled(min(allowed, left), self._stop):
                return None
            return f"not settled in {allowed:.1f} s"

        try:
            end = time.monotonic() + self.longest() - SEEN_WAIT
            return self._until_settled(move, end, f"look at {target}")
        except Unreachable as err:
            return str(err)

    def _until_settled(
        self, move: Callable[[float], str | None], end: float, what: str
    ) -> str | None:
        """Make ``move`` (given the seconds left until ``end``; it returns None once the head
        settled, else why not) until the head settles: None then, else why not. Gaze stopped
        by a fault on the way (a stale joint: a late servo reply) is engaged again by the next
        move, so the move is tried again after :data:`RETRY_PAUSE`, as long as there is time."""
        while (why := move(max(0.0, end - time.monotonic()))) is not None:
            state = self._gaze.status()
            if state["state"] != "stopped":
                return why
            why = f"gaze stopped: {state['problem']}"
            if time.monotonic() + RETRY_PAUSE >= end or self._stop.wait(RETRY_PAUSE):
                return why
            log.debug("%s again: %s", what, why)
        return None

    def back(self) -> None:
        """Turn the head back to where it was when the looker was made (the daemon makes it when
        the calibration sweep has brought the head back to where it started), and wait until it
        settled: a game's looks end there, where the robot saw the landmark boxes and its
        partner, so that it keeps seeing them (its estimate of the partner's pose comes from
        boxes seen within ``[landmarks] forget_after``). Gaze stopped by a fault on the way is
        engaged again after :data:`RETRY_PAUSE`, as long as a look may last."""
        if not self._home or not self._head.acquire(timeout=self.longest()):
            return
        try:
            # Tried again after a fault as a look is: tried once, a look back that met a late
            # servo reply left the head aside until the next game (for the rest of a demo run
            # when no game came: its boxes out of view, no peer pose).
            home = Fixation(dict(self._home))

            def move(left: float) -> str | None:  # no frames to wait for after it
                settled = self._gaze.run([home], 0.0, self._stop, "look_back")
                return None if settled else "not settled in time"

            why = self._until_settled(move, time.monotonic() + self.longest(), "look back")
            if why is not None and not self._stop.is_set():  # (not when the daemon stops)
                log.info("the look back was given up: %s", why)
        finally:
            self._head.release()

    def _given_up(self, target: tuple[float, float, float], reason: str) -> Look:
        where = ", ".join(f"{c:.3f}" for c in target)
        log.info("look at (%s) given up: %s", where, reason)
        return Look(False, reason)
