"""The experimenter's timeline compiled into where each object is at any time.

Objects move kinematically (no physics): a move slides an object along its path at constant
speed, a lay-down turns a standing object by 90 degrees about the bottom edge it falls over
(accelerating, like a fall), an addition or removal happens at once. Every placement is a pure
function of the scene time, so any frame can be rendered in any order with the same result.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from percept.kinematics.pose import axis_angle_matrix, rpy_matrix

if TYPE_CHECKING:
    from percept.drivers.sim.scene import Event, Scene, SimObject

_FLAT_SIDED = ("block", "cuboid", "toy")  # knocked over, these fall onto a side face
_CLEARANCE = 0.01  # metres between an object moved in front of another and that other


@dataclass(frozen=True)
class Placement:
    """Where an object is: ``R`` turns its own frame into the world frame, ``p`` is the centre
    of its bounding box in the world frame."""

    R: np.ndarray
    p: np.ndarray

    @property
    def standing(self) -> bool:
        """Upright: its own z axis points up."""
        return bool(self.R[2, 2] > 1.0 - 1e-9)

    def corners(self, size: np.ndarray) -> np.ndarray:
        """The 8 corners (8, 3) of a bounding box of ``size`` so placed, in the world frame."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return self.p + (signs * (np.asarray(size) / 2)) @ self.R.T


def standing(pose: tuple[float, float, float], height: float) -> Placement:
    """An upright object at ground pose ``(x, y, yaw)``."""
    x, y, yaw = pose
    return Placement(R=rpy_matrix((0.0, 0.0, yaw)), p=np.array([x, y, height / 2]))


@dataclass(frozen=True)
class _Motion:
    t0: float
    t1: float
    at: Callable[[float], Placement]  # s in [0, 1] -> placement
    end: Placement


class Track:
    """Where one object is and whether it is there, at any scene time."""

    def __init__(self, obj: SimObject) -> None:
        self.object = obj
        self.size = np.asarray(obj.size, dtype=float)
        self._start = standing(obj.pose, obj.size[2])
        self._presence: list[tuple[float, bool]] = [(-math.inf, obj.present)]
        self._motions: list[_Motion] = []

    def present(self, t: float) -> bool:
        """Whether the object is in the scene at time ``t``."""
        state = self._presence[0][1]
        for since, there in self._presence:
            if since <= t:
                state = there
        return state

    def placement(self, t: float) -> Placement:
        """Its placement at time ``t`` (also while absent: where it was last)."""
        current = self._start
        for m in self._motions:
            if m.t0 > t:
                break
            if t >= m.t1:
                current = m.end
            else:
                return m.at((t - m.t0) / (m.t1 - m.t0))
        return current

    def _busy_until(self) -> float:
        return self._motions[-1].t1 if self._motions else -math.inf

    def _add_motion(self, t0: float, span: float, at: Callable[[float], Placement]) -> None:
        self._motions.append(_Motion(t0, t0 + span, at, at(1.0)))

    def apply(self, e: Event, tracks: dict[int, Track], robots: dict[str, np.ndarray]) -> None:
        """Add event ``e``; ValueError if it cannot happen."""
        if e.t < self._busy_until():
            raise ValueError(f"the object is still moving until t={self._busy_until():g}")
        there = self.present(e.t)
        if e.action == "add":
            if there:
                raise ValueError("the object is already there")
            self._presence.append((e.t, True))
            if e.at is not None:
                now = self.placement(e.t)
                placed = Placement(now.R, np.array([e.at[0], e.at[1], now.p[2]]))
                self._add_motion(e.t, 0.0, lambda s: placed)
            return
        if not there:
            raise ValueError("the object is not there (removed, or not yet added)")
        if e.action == "remove":
            self._presence.append((e.t, False))
            return
        start = self.placement(e.t)
        if e.action == "lay_down":
            if not start.standing:
                raise ValueError("only a standing object can be laid down")
            heading = e.direction
            if self.object.shape in _FLAT_SIDED:
                heading = _nearest_side(start, heading)
            self._add_motion(e.t, e.span, _fall(start, self.size, heading))
            return
        if e.action == "move":
            waypoints = [start.p[:2], *(np.asarray(w, dtype=float) for w in e.path)]
        else:  # in_front
            if e.target is None or e.robot is None:  # Event checks this when it is built
                raise ValueError("in_front needs a target and a robot")
            target = tracks[e.target]
            if not target.present(e.t):
                raise ValueError(f"the target {e.target} is not there")
            centre = target.placement(e.t).p[:2]
            towards = robots[e.robot] - centre
            towards /= max(float(np.linalg.norm(towards)), 1e-9)
            distance = e.distance
            if distance is None:
                distance = _radius(target.size) + _radius(self.size) + _CLEARANCE
            waypoints = [start.p[:2], centre + distance * towards]
        self._add_motion(e.t, e.span, _slide(start, np.array(waypoints)))


def _radius(size: np.ndarray) -> float:
    """Half the diagonal of a footprint: a circle that holds the object however it is turned."""
    return float(math.hypot(size[0], size[1]) / 2)


def _slide(start: Placement, waypoints: np.ndarray) -> Callable[[float], Placement]:
    """Along the polyline through ``waypoints`` (x, y) at constant speed, height and attitude."""
    legs = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(legs)])
    total = float(along[-1])

    def at(s: float) -> Placement:
        d = min(max(s, 0.0), 1.0) * total
        x = np.interp(d, along, waypoints[:, 0]) if total > 0 else waypoints[-1, 0]
        y = np.interp(d, along, waypoints[:, 1]) if total > 0 else waypoints[-1, 1]
        return Placement(start.R, np.array([x, y, start.p[2]]))

    return at


def _nearest_side(start: Placement, heading: float) -> float:
    """The heading of the object's side face (outward normal) nearest to ``heading``: a box
    knocked over falls onto a face, not onto an edge."""
    normals = [sign * start.R[:, k] for k in (0, 1) for sign in (1, -1)]
    sides = [math.atan2(float(n[1]), float(n[0])) for n in normals]
    return min(sides, key=lambda a: abs(math.remainder(a - heading, 2 * math.pi)))


def _fall(start: Placement, size: np.ndarray, heading: float) -> Callable[[float], Placement]:
    """Knocked over towards ``heading``: a 90 degree turn about the bottom edge on that side."""
    d = np.array([math.cos(heading), math.sin(heading), 0.0])
    axis = np.cross([0.0, 0.0, 1.0], d)  # turning about it takes "up" towards d
    reach = float(np.max((start.corners(size) - start.p) @ d))
    pivot = np.array([start.p[0], start.p[1], 0.0]) + reach * d

    def at(s: float) -> Placement:
        s = min(max(s, 0.0), 1.0)
        turn = axis_angle_matrix(axis, (math.pi / 2) * s * s)
        return Placement(turn @ start.R, pivot + turn @ (start.p - pivot))

    return at


def compile_timeline(scene: Scene) -> dict[int, Track]:
    """Every object's :class:`Track`; ValueError naming the event that cannot happen."""
    tracks = {o.id: Track(o) for o in scene.objects}
    robots = {r.name: np.array(r.pose[:2], dtype=float) for r in scene.robots}
    order = sorted(range(len(scene.timeline)), key=lambda i: scene.timeline[i].t)
    for i in order:
        e = scene.timeline[i]
        if e.object is None:  # lights and exposure: see percept.drivers.sim.light
            continue
        try:
            tracks[e.object].apply(e, tracks, robots)
        except ValueError as err:
            raise ValueError(
                f"timeline[{i}] ({e.action} object {e.object} at t={e.t:g}): {err}"
            ) from None
    return tracks
