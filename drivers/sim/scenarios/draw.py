"""Scenes drawn at random from a :class:`~percept.drivers.sim.scenarios.distribution.Distribution`.

Scene number ``seed`` is drawn from a generator seeded with ``seed`` alone, so a scene is the
same whichever batch it was drawn in. Every scene has the same shape in time: the floor is empty
for the background calibration (a moving head sweeps its pan range meanwhile; a person may stand
there), then the objects are put down one after the other (an arm may reach in for each), then
the heads move as drawn while the experimenter moves, removes, knocks over and hides objects,
people walk through or stand beside the table and the light and the camera change.

The scene is returned as plain TOML data for a scene file (:mod:`percept.drivers.sim.scene`)
with the list of the factors drawn, which the file also carries as its header.
"""

from __future__ import annotations

import colorsys
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from percept.config.loader import TomlValue
from percept.drivers.sim.scenarios.distribution import Distribution, Range
from percept.drivers.sim.scene import ROUND_SHAPES, Color

_CALIBRATION_PAN_SPEED = 0.57  # rad/s of the calibration sweep (as in tabletop-look)
_SWEEP_MARGIN = 0.25  # the calibration sweep pans this much beyond the widest look, radians
_PLACE_EVERY = 0.7  # seconds between two objects put down by hand
_ARM = (0.08, 0.75)  # an arm reaching down from above: diameter, height (metres)
_ARM_TRAVEL = 0.6  # seconds an arm takes in and out
_ARM_PLACES = 2  # objects an arm puts down (the first ones; the rest are just there)
_AFTER_PLACING = 8.0  # seconds a scene lasts at least after the last object is down
_PEOPLE_ID = 101  # ids of people and arms (objects use 1..count)
FLOOR_LIKE = 14
"""Levels (0-255) by which each channel of a floor-like object's colour may differ from the
floor's."""
_FAR_BEARING = 1.1  # radians: the side of the table away from the robots (walks, boxes)


@dataclass(frozen=True)
class _Thing:
    """An object put on the floor: what later events need to know of it."""

    shape: str
    size: tuple[float, float, float]
    x: float
    y: float

    @property
    def radius(self) -> float:
        return math.hypot(self.size[0], self.size[1]) / 2


@dataclass(frozen=True)
class Scenario:
    """One drawn scene: its TOML data, the factors it holds and a header describing them."""

    data: dict[str, TomlValue]
    factors: tuple[str, ...]
    header: str


def _uniform(rng: np.random.Generator, r: Range) -> float:
    return float(rng.uniform(r[0], r[1])) if r[1] > r[0] else float(r[0])


def _r(x: float) -> float:
    return round(float(x), 4)


class _Draw:
    """The state of drawing one scene."""

    def __init__(self, dist: Distribution, seed: int, profiles: Mapping[str, str]) -> None:
        self.d = dist
        self.rng = np.random.default_rng(seed)
        self.seed = seed
        self.profiles = profiles
        self.factors: list[str] = []
        self.timeline: list[dict[str, TomlValue]] = []
        self.objects: list[TomlValue] = []  # the scene's object tables, people included
        self.things: dict[int, _Thing] = {}  # the objects to find, by id
        self.spots: list[tuple[float, float, float]] = []  # x, y, radius of what stands still
        self.next_person = _PEOPLE_ID
        self.times: list[float] = []  # each timeline event's time

    def chance(self, p: float, factor: str) -> bool:
        hit = bool(self.rng.random() < p)
        if hit:
            self.factors.append(factor)
        return hit

    def event(self, t: float, action: str, **keys: TomlValue) -> None:
        self.timeline.append({"t": _r(t), "action": action, **keys})
        self.times.append(_r(t))

    def timeline_order(self) -> list[tuple[float, TomlValue]]:
        return list(zip(self.times, self.timeline, strict=True))

    # -- the scene ----------------------------------------------------------------------------

    def scene(self) -> Scenario:
        d, rng = self.d, self.rng
        drawn = round(_uniform(rng, d.scene.duration), 1)
        modes = {r.name: self.head_mode() for r in d.robots}
        widest = d.heads.pan + _SWEEP_MARGIN
        moving = any(m != "still" for m in modes.values())
        calibration = d.scene.calibration
        if moving:
            calibration = max(calibration, round(4 * widest / _CALIBRATION_PAN_SPEED + 0.5, 1))
        floor_color = d.scene.floor_colors[int(rng.integers(len(d.scene.floor_colors)))]
        boxes = self.boxes()
        self.calibration_person(calibration)
        placed_until = self.place_objects(calibration, floor_color)
        duration = max(drawn, round(placed_until + _AFTER_PLACING, 1))
        busy_from = placed_until + 1.5
        self.object_events(busy_from, duration - 2.0)
        self.walkers(calibration, duration)
        self.stander(busy_from, duration)
        light = self.light(calibration + 1.0, duration - 2.0)
        camera = self.camera()
        robots: list[TomlValue] = [
            self.robot(
                r.name,
                r.profile,
                r.pose,
                modes[r.name],
                calibration,
                placed_until,
                duration,
                widest,
            )
            for r in d.robots
        ]
        name = f"{d.name}-{self.seed:04d}"
        data: dict[str, TomlValue] = {
            "name": name,
            "description": f"drawn from the distribution {d.name!r} with seed {self.seed}",
            "seed": self.seed,
            "duration": duration,
            "calibration": calibration,
            "floor": {
                "texture": d.scene.textures[int(rng.integers(len(d.scene.textures)))],
                "color": list(floor_color),
                "size": [6.0, 6.0],
                "tile": 0.5,
            },
            "lighting": light,
            "camera": camera,
            "robots": robots,
            "objects": self.objects,
            "boxes": boxes,
            "timeline": [e for _, e in sorted(self.timeline_order(), key=lambda k: k[0])],
        }
        header = (
            f"Scene {name}, drawn by percept scenarios from {d.name!r} (seed {self.seed}).\n"
            f"{duration:g} s; the first {calibration:g} s calibrate the background.\n"
            f"Factors: {', '.join(self.factors)}"
        )
        return Scenario(data, tuple(self.factors), header)

    # -- heads --------------------------------------------------------------------------------

    def head_mode(self) -> str:
        h = self.d.heads
        weights = np.array([h.still, h.fixations, h.sweep, h.gaze], dtype=float)
        mode = ("still", "fixations", "sweep", "gaze")[
            int(self.rng.choice(4, p=weights / weights.sum()))
        ]
        self.factors.append(f"head:{mode}")
        return mode

    def robot(
        self,
        name: str,
        profile: str,
        pose: tuple[float, float, float],
        mode: str,
        calibration: float,
        placed_until: float,
        duration: float,
        widest: float,
    ) -> dict[str, TomlValue]:
        h, rng = self.d.heads, self.rng
        tilt = _r(_uniform(rng, h.tilt))
        joints: dict[str, TomlValue] = {"head_tilt": {"offset": tilt}}
        if mode != "still":
            # the calibration sweep over the empty floor: 0 -> +w -> -w -> 0
            quarter = widest / _CALIBRATION_PAN_SPEED
            keys: list[list[float]] = [
                [0.0, 0.0],
                [quarter, widest],
                [3 * quarter, -widest],
                [4 * quarter, 0.0],
            ]
            t = max(placed_until + 0.5, keys[-1][0] + 0.1)
            keys.append([t, 0.0])
            keys += self.head_keys(mode, pose, t, duration)
            frames: list[TomlValue] = [[_r(a), _r(b)] for a, b in keys]
            joints["head_pan"] = {"keyframes": frames}
        return {"name": name, "profile": self.profiles[name], "pose": [*pose], "joints": joints}

    def head_keys(
        self, mode: str, pose: tuple[float, float, float], t: float, duration: float
    ) -> list[list[float]]:
        """Keyframes ``[t, pan]`` after ``t`` (the head at 0 then) up to ``duration``."""
        h, rng = self.d.heads, self.rng
        keys: list[list[float]] = []
        pan = 0.0
        while t < duration:
            if mode == "sweep":
                target = h.pan if pan <= 0 else -h.pan
                speed, hold = _uniform(rng, h.speed), 0.0
            elif mode == "fixations":
                target = float(rng.uniform(-h.pan, h.pan))
                speed, hold = _uniform(rng, h.speed), float(rng.uniform(2.0, 5.0))
            else:  # gaze: a quick turn to an object, a short look
                target = self.pan_to_object(pose)
                speed, hold = 3.0, float(rng.uniform(0.8, 2.5))
            t += max(abs(target - pan) / speed, 0.05)
            keys.append([t, target])
            if hold:
                t += hold
                keys.append([t, target])
            pan = target
        return keys

    def pan_to_object(self, pose: tuple[float, float, float]) -> float:
        """The pan that looks at one of the objects (within the largest pan)."""
        x, y, yaw = pose
        things = list(self.things.values())
        o = things[int(self.rng.integers(len(things)))]
        pan = math.remainder(math.atan2(o.y - y, o.x - x) - yaw, 2 * math.pi)
        return float(np.clip(pan, -self.d.heads.pan, self.d.heads.pan))

    # -- objects ------------------------------------------------------------------------------

    def free_spot(
        self,
        radius: float,
        area: float,
        near: tuple[float, float] | None = None,
        reach: float = 0.0,
        tries: int = 200,
    ) -> tuple[float, float] | None:
        """A place for a footprint of ``radius`` within ``area`` of (0, 0) (or within ``reach``
        of ``near``) clear of everything placed so far."""
        rng = self.rng
        for _ in range(tries):
            if near is None:
                r, a = area * math.sqrt(rng.random()), rng.uniform(0, 2 * math.pi)
                x, y = r * math.cos(a), r * math.sin(a)
            else:
                a = rng.uniform(0, 2 * math.pi)
                x, y = near[0] + reach * math.cos(a), near[1] + reach * math.sin(a)
                if math.hypot(x, y) > area:
                    continue
            if all(math.hypot(x - sx, y - sy) > radius + sr + 0.02 for sx, sy, sr in self.spots):
                return x, y
        return None

    def size(self, shape: str) -> tuple[float, float, float]:
        s, rng = self.d.objects.size, self.rng
        a, b, c = (_uniform(rng, s) for _ in range(3))
        if shape == "block":
            return a, a, a
        if shape == "ball":
            return a, a, a
        if shape in ROUND_SHAPES:
            return a, a, c
        return a, b, c

    def color(self, floor: Color) -> Color:
        o, rng = self.d.objects, self.rng
        u = rng.random()
        if u < o.p_dark:
            self.factors.append("color:dark")
            hsv = (rng.random(), rng.uniform(0.2, 0.8), rng.uniform(0.08, 0.23))
        elif u < o.p_dark + o.p_desaturated:
            self.factors.append("color:desaturated")
            hsv = (rng.random(), rng.uniform(0.0, 0.15), rng.uniform(0.3, 0.85))
        elif u < o.p_dark + o.p_desaturated + o.p_floor_like:
            self.factors.append("color:floor_like")
            r, g, b = (
                int(np.clip(c + rng.integers(-FLOOR_LIKE, FLOOR_LIKE + 1), 0, 255)) for c in floor
            )
            return (r, g, b)
        else:
            return o.colors[int(rng.integers(len(o.colors)))]
        red, green, blue = colorsys.hsv_to_rgb(*hsv)
        return (round(red * 255), round(green * 255), round(blue * 255))

    def place_objects(self, calibration: float, floor: Color) -> float:
        """Objects put down after the calibration; returns when the last is down."""
        o, rng = self.d.objects, self.rng
        n = int(rng.integers(o.count[0], o.count[1] + 1))
        self.factors.append(f"objects:{n}")
        arm = self.chance(self.d.people.p_arm, "people:arm")
        arm_id = self.next_person if arm else 0
        if arm:
            self.next_person += 1
            self.objects.append(self.person(arm_id, "arm", _ARM[0], _ARM[1], (3.0, 0.0)))
        t = calibration + 0.5
        colors: list[Color] = []
        for i in range(1, n + 1):
            shape = o.shapes[int(rng.integers(len(o.shapes)))]
            for attempt in range(100):
                size = self.size(shape) if attempt < 50 else (o.size[0],) * 3
                radius = math.hypot(size[0], size[1]) / 2
                spot = self.free_spot(radius, o.area)
                if spot is not None:
                    break
            else:
                continue  # the table is full
            color = self.color(floor)
            if colors and self.chance(o.p_same_color / max(n - 1, 1), "color:same"):
                color = colors[int(rng.integers(len(colors)))]
            colors.append(color)
            self.factors.append(f"shape:{shape}")
            self.factors.append(f"size:{max(size):.2f}")
            yaw = float(rng.uniform(-math.pi, math.pi))
            self.spots.append((spot[0], spot[1], radius))
            rounded = (_r(size[0]), _r(size[1]), _r(size[2]))  # as the scene file has it
            self.things[i] = _Thing(shape, rounded, _r(spot[0]), _r(spot[1]))
            self.objects.append(
                {
                    "id": i,
                    "name": f"{shape}-{i}",
                    "shape": shape,
                    "size": [_r(v) for v in size],
                    "color": list(color),
                    "pose": [_r(spot[0]), _r(spot[1]), _r(yaw)],
                    "present": False,
                }
            )
            by_arm = arm and i <= _ARM_PLACES
            if by_arm:
                t = self.reach_in(arm_id, spot, radius, t)
            self.event(t, "add", object=i)
            if by_arm:
                t = self.reach_out(arm_id, spot, t)
            t += _PLACE_EVERY
        self.factors.append("event:placed")
        return t

    def reach_in(self, arm: int, spot: tuple[float, float], radius: float, t: float) -> float:
        """The arm comes in from the far side to beside ``spot``; returns when it is there."""
        bearing = math.atan2(spot[1], spot[0]) if math.hypot(*spot) > 0.05 else _FAR_BEARING
        start = (spot[0] + 0.6 * math.cos(bearing), spot[1] + 0.6 * math.sin(bearing))
        beside = radius + _ARM[0] / 2 + 0.01
        there = (spot[0] + beside * math.cos(bearing), spot[1] + beside * math.sin(bearing))
        self.event(t, "add", object=arm, at=[_r(start[0]), _r(start[1])])
        self.event(t, "move", object=arm, path=[[_r(there[0]), _r(there[1])]], duration=_ARM_TRAVEL)
        return t + _ARM_TRAVEL + 0.05

    def reach_out(self, arm: int, spot: tuple[float, float], t: float) -> float:
        bearing = math.atan2(spot[1], spot[0]) if math.hypot(*spot) > 0.05 else _FAR_BEARING
        away = (spot[0] + 0.6 * math.cos(bearing), spot[1] + 0.6 * math.sin(bearing))
        self.event(
            t + 0.2, "move", object=arm, path=[[_r(away[0]), _r(away[1])]], duration=_ARM_TRAVEL
        )
        self.event(t + 0.25 + _ARM_TRAVEL, "remove", object=arm)
        return t + 0.3 + _ARM_TRAVEL

    def object_events(self, t0: float, t1: float) -> None:
        """Moves, removals, knocks and hidings, each on an object of its own."""
        o, rng = self.d.objects, self.rng
        free = [int(i) for i in rng.permutation(list(self.things))]
        removed: set[int] = set()
        if t1 - t0 < 3.0:
            return

        def when() -> float:
            return float(rng.uniform(t0, t1 - 2.5))

        for action, p in (
            ("move", o.p_move),
            ("remove", o.p_remove),
            ("knock", o.p_knock),
            ("hide", o.p_hide),
        ):
            if not free or not self.chance(p, f"event:{action}"):
                continue
            i = free.pop()
            obj = self.things[i]
            t = when()
            if action == "remove":
                self.event(t, "remove", object=i)
                removed.add(i)
            elif action == "knock":
                if obj.shape == "ball":
                    self.event(t, "remove", object=i)  # a ball is not knocked over: it goes
                    removed.add(i)
                    continue
                self.event(t, "lay_down", object=i, direction=_r(rng.uniform(-math.pi, math.pi)))
            elif action == "move":
                radius = obj.radius
                reach = float(rng.uniform(0.06, 0.15))
                spot = self.free_spot(radius, o.area + 0.05, (obj.x, obj.y), reach)
                if spot is None:
                    continue
                self.spots.append((spot[0], spot[1], radius))
                self.event(
                    t,
                    "move",
                    object=i,
                    path=[[_r(spot[0]), _r(spot[1])]],
                    duration=_r(rng.uniform(1.0, 3.0)),
                )
            else:  # hide: moved in front of another, as one robot sees it
                targets = [j for j in free if j not in removed]
                if not targets:
                    continue
                j = targets[int(rng.integers(len(targets)))]
                free.remove(j)
                robot = self.d.robots[int(rng.integers(len(self.d.robots)))].name
                self.event(t, "in_front", object=i, target=j, robot=robot)

    # -- people -------------------------------------------------------------------------------

    def person(
        self,
        pid: int,
        name: str,
        width: float,
        height: float,
        at: tuple[float, float],
        present: bool = False,
    ) -> dict[str, TomlValue]:
        colors = self.d.people.colors
        color = colors[int(self.rng.integers(len(colors)))]
        return {
            "id": pid,
            "name": name,
            "shape": "figure",
            "size": [_r(width), _r(width), _r(height)],
            "color": list(color),
            "pose": [_r(at[0]), _r(at[1]), 0.0],
            "present": present,
        }

    def new_person(self, at: tuple[float, float], present: bool = False) -> int:
        p = self.d.people
        pid = self.next_person
        self.next_person += 1
        height = _uniform(self.rng, p.height)
        self.objects.append(self.person(pid, f"person-{pid}", height * 0.19, height, at, present))
        return pid

    def far_point(self, distance: float, spread: float = 0.6) -> tuple[float, float]:
        a = _FAR_BEARING + float(self.rng.uniform(-spread, spread))
        return distance * math.cos(a), distance * math.sin(a)

    def walk(self, pid: int, t: float, distance: float) -> float:
        """A walk through the view, along a line ``distance`` beyond the table on the far side;
        returns when the walker is gone."""
        a = _FAR_BEARING + float(self.rng.uniform(-0.5, 0.5))
        u = np.array([math.cos(a), math.sin(a)])
        v = np.array([-u[1], u[0]]) * (1 if self.rng.random() < 0.5 else -1)
        start, end = distance * u - 2.0 * v, distance * u + 2.0 * v
        span = float(self.rng.uniform(3.0, 4.5))
        self.event(t, "add", object=pid, at=[_r(start[0]), _r(start[1])])
        self.event(t, "move", object=pid, path=[[_r(end[0]), _r(end[1])]], duration=_r(span))
        self.event(t + span + 0.1, "remove", object=pid)
        return t + span + 0.2

    def calibration_person(self, calibration: float) -> None:
        if not self.chance(self.d.people.p_calibration, "people:calibration"):
            return
        spot = self.far_point(float(self.rng.uniform(0.95, 1.2)))
        pid = self.new_person(spot, present=True)
        out = (spot[0] * 2.5, spot[1] * 2.5)
        self.event(
            calibration + 0.3, "move", object=pid, path=[[_r(out[0]), _r(out[1])]], duration=2.0
        )
        self.event(calibration + 2.4, "remove", object=pid)

    def walkers(self, calibration: float, duration: float) -> None:
        p = self.d.people
        if not self.chance(p.p_walk, "people:walk"):
            return
        for _ in range(int(self.rng.integers(p.walkers[0], p.walkers[1] + 1))):
            pid = self.new_person((0.0, 3.0))
            t = float(self.rng.uniform(calibration + 1.0, max(calibration + 1.0, duration - 5.0)))
            self.walk(pid, t, float(self.rng.uniform(0.95, 1.5)))

    def stander(self, t0: float, duration: float) -> None:
        p = self.d.people
        if duration - t0 < 4.0 or not self.chance(p.p_stand, "people:stand"):
            return
        stay = _uniform(self.rng, p.stand_seconds)
        self.factors.append(f"stand:{stay:.0f}s")
        for _ in range(50):
            spot = self.far_point(float(self.rng.uniform(0.7, 0.95)), 0.9)
            if all(math.hypot(spot[0] - x, spot[1] - y) > r + 0.2 for x, y, r in self.spots):
                break
        else:
            return
        pid = self.new_person((spot[0] * 2.5, spot[1] * 2.5))
        t = float(self.rng.uniform(t0, max(t0, duration - stay - 3.0)))
        start = (spot[0] * 2.5, spot[1] * 2.5)
        self.event(t, "add", object=pid, at=[_r(start[0]), _r(start[1])])
        self.event(t, "move", object=pid, path=[[_r(spot[0]), _r(spot[1])]], duration=1.5)
        self.event(
            t + 1.5 + stay, "move", object=pid, path=[[_r(start[0]), _r(start[1])]], duration=1.5
        )
        self.event(t + 3.1 + stay, "remove", object=pid)

    # -- boxes, light, camera -----------------------------------------------------------------

    def boxes(self) -> list[TomlValue]:
        b, rng = self.d.boxes, self.rng
        out: list[TomlValue] = []
        for box in (1, 2):
            for _ in range(200):
                dist, bearing = _uniform(rng, b.distance), _uniform(rng, b.bearing)
                x, y = dist * math.cos(bearing), dist * math.sin(bearing)
                if all(math.hypot(x - sx, y - sy) > 0.13 + sr + 0.03 for sx, sy, sr in self.spots):
                    break
            self.spots.append((x, y, 0.13))
            self.factors.append(f"box:{dist:.2f}m")
            first = 4 * (box - 1)
            faces = ("front", "left", "back", "right")
            markers: list[TomlValue] = [
                {"id": first + k, "side": 0.1, "face": f} for k, f in enumerate(faces)
            ]
            out.append(
                {
                    "id": box,
                    "size": [0.18, 0.18, 0.18],
                    "pose": [_r(x), _r(y), _r(rng.uniform(-math.pi, math.pi))],
                    "markers": markers,
                }
            )
        return out

    def light(self, t0: float, t1: float) -> dict[str, TomlValue]:
        li, rng = self.d.light, self.rng
        n = int(rng.integers(li.lamps[0], li.lamps[1] + 1))
        self.factors.append(f"lamps:{n}")
        lamps: list[TomlValue] = []
        for _ in range(n):
            a, tilt = rng.uniform(-math.pi, math.pi), rng.uniform(0.15, 0.6)
            lamps.append(
                {
                    "direction": [_r(tilt * math.cos(a)), _r(tilt * math.sin(a)), -1.0],
                    "diffuse": [_r(_uniform(rng, li.diffuse))] * 3,
                }
            )
        ambient = _r(_uniform(rng, li.ambient))
        span = t1 - t0
        drift_from = t0
        if span > 8.0 and self.chance(li.p_switch, "light:switch"):
            t = float(rng.uniform(t0, t0 + span / 2 - 4.0))
            back = t + float(rng.uniform(1.5, 4.0))
            self.event(t, "lights", scale=_r(_uniform(rng, li.switch)))
            self.event(back, "lights", scale=1.0)
            drift_from = back + 1.0
        if span > 4.0 and drift_from < t1 - 3.0 and self.chance(li.p_drift, "light:drift"):
            drift = _uniform(rng, li.drift)
            up = self.chance(li.p_brighter, "light:brighter")
            scale = 1.0 + drift / 2 if up else 1.0 - drift
            self.factors.append(f"drift:{drift:.2f}")
            seconds = _r(_uniform(rng, li.drift_seconds))
            self.factors.append(f"drift_seconds:{seconds:.0f}")
            self.event(
                float(rng.uniform(drift_from, t1 - 3.0)),
                "lights",
                scale=_r(scale),
                duration=seconds,
            )
        if n >= 2 and span > 2.0 and self.chance(li.p_uneven, "light:uneven"):
            self.event(
                float(rng.uniform(t0, t1)),
                "lights",
                lamp=int(rng.integers(n)),
                scale=_r(_uniform(rng, li.uneven)),
                duration=_r(rng.choice([0.0, 3.0])),
            )
        if span > 2.0 and self.chance(li.p_exposure, "camera:exposure"):
            self.event(float(rng.uniform(t0, t1)), "exposure", scale=_r(_uniform(rng, li.exposure)))
        if span > 2.0 and self.chance(li.p_white_balance, "camera:white_balance"):
            gains: list[TomlValue] = [_r(_uniform(rng, li.white_balance)) for _ in range(3)]
            self.event(float(rng.uniform(t0, t1)), "white_balance", gains=gains)
        return {"ambient": [ambient, ambient, ambient], "lights": lamps}

    def camera(self) -> dict[str, TomlValue]:
        c, li, rng = self.d.camera, self.d.light, self.rng
        out: dict[str, TomlValue] = {
            "noise": _r(_uniform(rng, c.noise)),
            "shutter": _r(_uniform(rng, c.shutter)),
        }
        if self.chance(li.p_flicker, "camera:flicker"):
            out["flicker"] = _r(_uniform(rng, li.flicker))
            out["flicker_hz"] = float(li.flicker_hz[int(rng.integers(len(li.flicker_hz)))])
        if self.chance(c.p_jpeg, "camera:jpeg"):
            quality = int(rng.integers(c.jpeg_quality[0], c.jpeg_quality[1] + 1))
            out["jpeg_quality"] = quality
            self.factors.append(f"jpeg:{quality}")
        return out


def draw_scene(dist: Distribution, seed: int, profiles: Mapping[str, str]) -> Scenario:
    """Scene number ``seed`` of ``dist``; ``profiles`` gives, per robot name, the text its
    ``profile`` key gets (a shipped name or a path from where the scene file is written)."""
    return _Draw(dist, seed, profiles).scene()
