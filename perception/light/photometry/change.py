"""Sudden changes of light: a lamp switched, a camera's exposure stepping.

Two signs. The fitted gain of Y moving by more than ``switch_gain`` (relative) within
``switch_window`` seconds or since the last frame is a global change, which the compensation
absorbs; slow drift and a camera's flicker move the gain by far less in a quarter of a second.
The share of foreground outside the anchors jumping by ``switch_fraction`` from one frame to the
next is a change the compensation cannot explain, or something large entering the view: a
person walking past close to the camera covers half the image between two frames at 5 frames a
second. The two differ in what follows: after a lamp the view is still, a person keeps moving.
So the jump is held until the view has been still for ``confirm`` seconds, and only then taken
for light and the background re-learned; when the share falls back, whatever it was has gone
and nothing is re-learned. Meanwhile neither the foreground nor a jump of the gain (a body
covering most of the view drags the fit along) is trusted, and the anchors stand as they were.
The light is steady again when no change was seen for ``settle`` seconds.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

from percept.perception.params import LightParams

STILL = 0.05
"""Share of the held foreground that may change between frames with the view still: noise and
the compensation's small corrections, while a body walking past moves its whole outline."""


class Change(Enum):
    """What one frame showed."""

    NONE = "none"
    GLOBAL = "global"
    """A sudden change the compensation explains (a switch, an exposure step)."""
    UNEXPLAINED = "unexplained"
    """A sudden change it does not explain, confirmed by a still view: re-learn the background."""


@dataclass
class _Hold:
    """A jump of the foreground share not yet explained."""

    base: float
    """The share before the jump."""
    still_since: float | None = None
    """Time of the frame since which the view has been still (None: it moved)."""


class ChangeDetector:
    """Watches the gain and the foreground share frame by frame."""

    def __init__(self, params: LightParams) -> None:
        self.params = params
        self._gains: deque[tuple[float, float]] = deque()
        self._share: float | None = None
        self._t: float | None = None
        self._hold: _Hold | None = None
        self.last: float = -math.inf
        """Time of the last sudden change (-inf: none yet)."""
        self.count = 0
        """Sudden changes seen."""

    @property
    def holding(self) -> bool:
        """A jump of the foreground is held: the foreground outside the anchors is not to be
        trusted (no new anchor there) until it is confirmed or gone."""
        return self._hold is not None

    def update(self, t: float, gain: float, share: float, moved: Callable[[], float]) -> Change:
        """The change at time ``t`` given the fitted Y ``gain``, the foreground ``share``
        outside the anchors (0-1), and ``moved``: the share of that foreground that changed
        since the last frame (asked only while a jump is held)."""
        p = self.params
        gains = self._gains
        # the last frame's gain always counts: at a low frame rate a switch falls between
        # frames further apart than the window
        while len(gains) > 1 and gains[0][0] < t - p.switch_window:
            gains.popleft()
        jump = any(abs(gain - g) > p.switch_gain * max(g, 1e-3) for _, g in gains)
        gains.append((t, gain))
        before, self._share = self._share, share
        if self._hold is None and before is not None and share - before > p.switch_fraction:
            self._hold = _Hold(base=before)
        change = Change.GLOBAL if jump else Change.NONE
        if self._hold is not None:
            # the gain fitted while a body covers most of the view jumps as well: it counts
            # only once the view has come to rest
            confirmed = self._confirmed(t, share, moved)
            change = Change.UNEXPLAINED if confirmed else Change.NONE
        self._t = t
        if change is Change.NONE:
            return change
        if t - self.last > p.switch_window:  # one switch, seen over several frames, counts once
            self.count += 1
        self.last = t
        return change

    def _confirmed(self, t: float, share: float, moved: Callable[[], float]) -> bool:
        """Whether the held jump is now taken for light (ends the hold, as does its going)."""
        hold, p = self._hold, self.params
        assert hold is not None
        if share < hold.base + p.switch_fraction / 2:  # gone: something passed through the view
            self._hold = None
            return False
        if moved() > STILL:
            hold.still_since = None
            return False
        if hold.still_since is None:  # still since the frame before this one
            hold.still_since = self._t if self._t is not None else t
        if t - hold.still_since < p.confirm:
            return False
        self._hold = None
        return True

    def steady(self, t: float) -> bool:
        """No sudden change in the last ``settle`` seconds."""
        return t - self.last >= self.params.settle
