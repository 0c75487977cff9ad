"""The light and the cameras' exposure over a scene's time, from its ``lights`` and ``exposure``
events.

Each is a multiple of the scene's own (1 at the start): an event takes it from where it is at the
event's time to the event's ``scale`` in a linear ramp of the event's ``duration`` (0: at once),
so slow drift, a switch and an exposure step are one mechanism. A later event starts from where
an earlier ramp has got to. Like the rest of the world, the level is a pure function of time.
"""

from __future__ import annotations

from dataclasses import dataclass

from percept.drivers.sim.scene import Scene


@dataclass(frozen=True)
class _Ramp:
    t0: float
    t1: float
    start: float
    end: float


class Level:
    """A multiple of the scene's light (or exposure) at any scene time."""

    def __init__(self, events: list[tuple[float, float, float]]) -> None:
        """``events``: (time, scale, duration), in any order."""
        self._ramps: list[_Ramp] = []
        for t, scale, duration in sorted(events):
            self._ramps.append(_Ramp(t, t + duration, self.at(t), scale))

    @property
    def constant(self) -> bool:
        """Never changes."""
        return not self._ramps

    def at(self, t: float) -> float:
        """The multiple at scene time ``t``."""
        level = 1.0
        for r in self._ramps:
            if t < r.t0:
                break
            done = 1.0 if t >= r.t1 else (t - r.t0) / (r.t1 - r.t0)
            level = r.start + (r.end - r.start) * done
        return level


def levels(scene: Scene) -> tuple[Level, Level]:
    """The light's and the exposure's :class:`Level` of ``scene``."""
    out = []
    for action in ("lights", "exposure"):
        events = [
            (e.t, e.scale, e.span)
            for e in scene.timeline
            if e.action == action and e.scale is not None
        ]
        out.append(Level(events))
    return out[0], out[1]
