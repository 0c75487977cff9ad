"""Sudden changes of light: a lamp switched, a camera's exposure stepping.

Two signs, either enough: the fitted gain of Y moves by more than ``switch_gain`` (relative)
within ``switch_window`` seconds or since the last frame (a global change, which the
compensation absorbs), or the share of foreground outside the anchors jumps by
``switch_fraction`` from one frame to the next (a change the compensation cannot explain; the
background must be re-learned). Slow drift and a camera's flicker move the gain by far less in a
quarter of a second. The light is steady again when neither sign was seen for ``settle`` seconds.
"""

from __future__ import annotations

import math
from collections import deque
from enum import Enum

from percept.perception.params import LightParams


class Change(Enum):
    """What one frame showed."""

    NONE = "none"
    GLOBAL = "global"
    """A sudden change the compensation explains (a switch, an exposure step)."""
    UNEXPLAINED = "unexplained"
    """A sudden change it does not explain: re-learn the background."""


class ChangeDetector:
    """Watches the gain and the foreground share frame by frame."""

    def __init__(self, params: LightParams) -> None:
        self.params = params
        self._gains: deque[tuple[float, float]] = deque()
        self._share: float | None = None
        self.last: float = -math.inf
        """Time of the last sudden change (-inf: none yet)."""
        self.count = 0
        """Sudden changes seen."""

    def update(self, t: float, gain: float, share: float) -> Change:
        """The change at time ``t`` given the fitted Y ``gain`` and the foreground ``share``
        outside the anchors (0-1)."""
        p = self.params
        gains = self._gains
        # the last frame's gain always counts: at a low frame rate a switch falls between
        # frames further apart than the window
        while len(gains) > 1 and gains[0][0] < t - p.switch_window:
            gains.popleft()
        jump = any(abs(gain - g) > p.switch_gain * max(g, 1e-3) for _, g in gains)
        gains.append((t, gain))
        before, self._share = self._share, share
        if before is not None and share - before > p.switch_fraction:
            change = Change.UNEXPLAINED
        elif jump:
            change = Change.GLOBAL
        else:
            return Change.NONE
        if t - self.last > p.switch_window:  # one switch, seen over several frames, counts once
            self.count += 1
        self.last = t
        return change

    def steady(self, t: float) -> bool:
        """No sudden change in the last ``settle`` seconds."""
        return t - self.last >= self.params.settle
