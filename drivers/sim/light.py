"""The light and the cameras' exposure and white balance over a scene's time, from its
``lights``, ``exposure`` and ``white_balance`` events.

Each is a multiple of the scene's own (1 at the start): an event takes it from where it is at the
event's time to the event's ``scale`` in a linear ramp of the event's ``duration`` (0: at once),
so slow drift, a switch and an exposure step are one mechanism. A later event starts from where
an earlier ramp has got to. Like the rest of the world, the level is a pure function of time.
A ``lights`` event with a ``lamp`` changes that lamp alone; each lamp, the ambient light and each
white-balance channel has its own level.
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


@dataclass(frozen=True)
class Levels:
    """Every level of a scene: each lamp's, the ambient light's, the exposure's and the red,
    green and blue white-balance gains'."""

    lamps: tuple[Level, ...]
    ambient: Level
    exposure: Level
    white_balance: tuple[Level, Level, Level]

    @property
    def light_constant(self) -> bool:
        return self.ambient.constant and all(lamp.constant for lamp in self.lamps)


def levels(scene: Scene) -> Levels:
    """The :class:`Levels` of ``scene``."""
    timeline = scene.timeline
    lights = [
        (e.t, e.scale, e.span, e.lamp)
        for e in timeline
        if e.action == "lights" and e.scale is not None
    ]
    lamps = tuple(
        Level([(t, scale, span) for t, scale, span, lamp in lights if lamp in (None, k)])
        for k in range(len(scene.lighting.lights))
    )
    ambient = Level([(t, scale, span) for t, scale, span, lamp in lights if lamp is None])
    exposure = Level(
        [(e.t, e.scale, e.span) for e in timeline if e.action == "exposure" and e.scale is not None]
    )
    balance = [
        (e.t, e.gains, e.span)
        for e in timeline
        if e.action == "white_balance" and e.gains is not None
    ]
    r, g, b = (Level([(t, gains[c], span) for t, gains, span in balance]) for c in range(3))
    return Levels(lamps, ambient, exposure, (r, g, b))
