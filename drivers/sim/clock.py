"""Scene time: which moment of the scene the simulated camera and joints show.

The world is a pure function of scene time, so all a simulated device needs is a clock that says
what the scene time is now, and what it was at an earlier monotonic time (the time stamp of a
frame or a joint reading). Two kinds:

- :class:`WallClock`: scene time runs with wall-clock time from an ``epoch`` (``time.time()`` at
  scene time 0), so several processes given the same epoch show the same moment. It can be held
  at 0 (the empty scene, e.g. while a background model is calibrated) and starts when released.
- :class:`StepClock`: scene time advances only when a frame is taken, by one frame period, so a
  run shows frame k at scene time k / fps however fast or slow it is processed.
"""

from __future__ import annotations

import bisect
import threading
import time
from collections import deque
from typing import Protocol


class SceneClock(Protocol):
    """What simulated devices ask a clock."""

    def next_frame(self, period: float, t: float) -> float:
        """The scene time of a frame taken at monotonic time ``t`` (a stepped clock advances)."""
        ...

    def at(self, t: float) -> float:
        """The scene time at monotonic time ``t``."""
        ...


class WallClock:
    """Scene time ``time.time() - epoch`` (never below 0); 0 while held or before an epoch.

    With a ``period`` the scene starts again from 0 every ``period`` seconds (long runs of a
    short scene, e.g. a soak test).
    """

    def __init__(
        self, epoch: float | None = None, hold: bool = False, period: float | None = None
    ) -> None:
        if period is not None and period <= 0:
            raise ValueError(f"period must be positive, got {period}")
        self.epoch = epoch
        self.hold = hold
        self.period = period

    def release(self) -> None:
        """Let time run; without an epoch, scene time 0 is now."""
        self.hold = False
        if self.epoch is None:
            self.epoch = time.time()

    def now(self) -> float:
        return self.at(time.monotonic())

    def at(self, t: float) -> float:
        if self.hold or self.epoch is None:
            return 0.0
        wall = time.time() - (time.monotonic() - t)
        scene = max(0.0, wall - self.epoch)
        return scene if self.period is None else scene % self.period

    def next_frame(self, period: float, t: float) -> float:
        return self.at(t)


class StepClock:
    """Scene time that advances one frame period per frame taken, starting at ``start``.

    It remembers when (monotonic) each step was taken, so a reading stamped between two frames
    gets the scene time of the earlier one.
    """

    def __init__(self, start: float = 0.0, memory: int = 4096) -> None:
        self._lock = threading.Lock()
        self._next = start
        self._stamps: deque[float] = deque(maxlen=memory)
        self._times: deque[float] = deque(maxlen=memory)

    def next_frame(self, period: float, t: float) -> float:
        with self._lock:
            scene = self._next
            self._next += period
            self._stamps.append(t)
            self._times.append(scene)
            return scene

    def at(self, t: float) -> float:
        with self._lock:
            if not self._stamps:
                return self._next
            i = bisect.bisect_right(self._stamps, t)
            return self._times[max(i - 1, 0)]
