"""Runs of like incidents, and a bound on the log lines about them.

A bad sender repeats itself: the same malformed message a thousand times, a peer whose boxes lie
ten kilometres away at every tick, a bug in this process's own messages at every frame. What a
status and a log should say about such a run is that it is going on, how many so far and why
the first one happened: a :class:`Run`. It ends after ``quiet`` seconds without an incident, so
a fault it causes clears by itself. :class:`LogLimit` keeps the log readable (and its file
bounded) while any number of incidents arrive.
"""

from __future__ import annotations

import math
from collections import deque


class Run:
    """Incidents of one kind from one source: ``total`` ever, ``count`` in the current run and
    the run's first ``reason``. Not thread-safe: the owner holds its lock."""

    def __init__(self, quiet: float = 2.0) -> None:
        self.quiet = quiet
        self.total = 0
        self.count = 0
        self.reason = ""
        self.last = -math.inf

    def add(self, reason: str, now: float) -> bool:
        """One more incident at ``now``; whether it began a new run."""
        began = now - self.last > self.quiet
        if began:
            self.count, self.reason = 0, reason
        self.count += 1
        self.total += 1
        self.last = now
        return began

    def active(self, now: float) -> bool:
        """Whether the run goes on: its last incident is at most ``quiet`` seconds old."""
        return now - self.last <= self.quiet


class LogLimit:
    """At most ``most`` log lines in any ``window`` seconds; :meth:`allow` says whether one
    more may go now, and how many were held back since the last one that went."""

    def __init__(self, most: int = 10, window: float = 10.0) -> None:
        self.window = window
        self._sent: deque[float] = deque(maxlen=most)
        self.held = 0

    def allow(self, now: float) -> bool:
        if len(self._sent) == self._sent.maxlen and now - self._sent[0] < self.window:
            self.held += 1
            return False
        self._sent.append(now)
        return True

    def take_held(self) -> int:
        """Lines held back since the last call (say so in the next line that goes)."""
        held, self.held = self.held, 0
        return held
