"""Scene files (``config/scenes/*.toml``): what the simulated world holds and what happens in it.

The world frame has its origin on the floor, x and y along it, z up; lengths in metres, angles in
radians, times in seconds from the start of the scene. A robot stands at a ground pose
``(x, y, yaw)``: its ground frame (SPEC §3) is there. An object's ``pose`` ``(x, y, yaw)`` puts
the centre of its footprint there, standing upright; its ``size`` is its bounding box in its own
frame (x, y, then height). A carton box's frame is the landmark convention (origin on the floor
at the centre of its footprint, x towards its ``front`` face, y towards its ``left`` face, z up)
and its ``size`` is (length front-back, width, height).

Colours are 8-bit RGB. Objects and boxes have integer ids; object ids are the track ids of the
ground truth (MOTChallenge wants them numeric and positive).
"""

from __future__ import annotations

import itertools
import math
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from percept.kinematics.pose import transform

Vec3 = tuple[float, float, float]
Color = tuple[int, int, int]
GroundPose = tuple[float, float, float]

MAX_ROBOTS = 4  # each robot's body gets its own MuJoCo geom group (1-4) so its camera skips it
_NAME = re.compile(r"^[A-Za-z0-9_-]+$")

Shape = Literal["block", "cuboid", "cylinder", "cone", "ball", "toy", "figure"]
ROUND_SHAPES = ("cylinder", "cone", "figure")
Action = Literal[
    "add", "remove", "move", "lay_down", "in_front", "lights", "exposure", "white_balance"
]
LIGHT_ACTIONS = ("lights", "exposure", "white_balance")
"""Actions on the light and the cameras, not on an object."""
Face = Literal["front", "back", "left", "right"]

#: Seconds an action takes when the event does not say.
DEFAULT_DURATION: dict[str, float] = {"move": 2.0, "lay_down": 0.5, "in_front": 1.5}


class SceneError(ValueError):
    """A scene that cannot be simulated; ``key`` is where in the scene file the problem is."""

    def __init__(self, key: str, problem: str) -> None:
        self.key = key
        self.problem = problem
        super().__init__(f"{key}: {problem}" if key else problem)


@dataclass(frozen=True)
class Floor:
    """The floor: a rectangle with a procedural texture (never a flat colour)."""

    texture: Literal["wood", "carpet", "tiles"] = field(
        default="wood", metadata={"doc": "procedural pattern: wood, carpet or tiles"}
    )
    color: Color = field(
        default=(176, 134, 94), metadata={"min": 0, "max": 255, "doc": "base colour, RGB"}
    )
    size: tuple[float, float] = field(
        default=(4.0, 4.0), metadata={"min": 0.1, "max": 100.0, "doc": "x and y extent, metres"}
    )
    tile: float = field(
        default=0.6, metadata={"min": 0.01, "max": 100.0, "doc": "metres one texture image covers"}
    )


@dataclass(frozen=True)
class Light:
    """One lamp; a directional one is like the sun (no position, no fall-off)."""

    direction: Vec3 = field(
        default=(0.3, 0.2, -1.0), metadata={"min": -1000.0, "max": 1000.0, "doc": "where it shines"}
    )
    position: Vec3 = field(
        default=(0.0, 0.0, 3.0),
        metadata={"min": -1000.0, "max": 1000.0, "doc": "metres (spot lights)"},
    )
    diffuse: tuple[float, float, float] = field(
        default=(0.6, 0.6, 0.6), metadata={"min": 0.0, "max": 1.0, "doc": "RGB intensity"}
    )
    directional: bool = field(default=True, metadata={"doc": "directional or spot light"})

    def __post_init__(self) -> None:
        if not any(self.direction):
            raise ValueError("light direction must not be zero")


@dataclass(frozen=True)
class Lighting:
    """Ambient light, lamps and shadows."""

    ambient: tuple[float, float, float] = field(
        default=(0.45, 0.45, 0.45), metadata={"min": 0.0, "max": 1.0, "doc": "RGB ambient light"}
    )
    lights: tuple[Light, ...] = field(default=(Light(),), metadata={"doc": "lamps"})
    shadows: int = field(
        default=0,
        metadata={
            "min": 0,
            "max": 8192,
            "doc": "shadow map size in pixels; 0 turns shadows off (rendering is then far cheaper)",
        },
    )


@dataclass(frozen=True)
class CameraEffects:
    """What a real camera adds to every frame: sensor noise and exposure flicker."""

    noise: float = field(
        default=0.0,
        metadata={"min": 0.0, "max": 100.0, "doc": "std dev of Gaussian pixel noise, 0-255 scale"},
    )
    flicker: float = field(
        default=0.0,
        metadata={"min": 0.0, "max": 0.9, "doc": "relative amplitude of exposure changes"},
    )
    flicker_hz: float = field(
        default=0.0,
        metadata={
            "min": 0.0,
            "max": 1000.0,
            "doc": "0: a new random exposure every frame; > 0: a sinusoid of this frequency",
        },
    )
    jpeg_quality: int = field(
        default=0,
        metadata={
            "min": 0,
            "max": 100,
            "doc": "0: frames as rendered; 1-100: each frame JPEG-compressed at this quality",
        },
    )
    shutter: float = field(
        default=0.0,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "exposure time, seconds: a head turning during it blurs the frame (0: none)",
        },
    )


@dataclass(frozen=True)
class JointMotion:
    """How one joint moves: ``offset + amplitude * sin(2 pi t / period + phase)``, or linear
    between ``keyframes`` ``[[t, angle], ...]`` (held before the first and after the last, or
    repeated with ``loop``)."""

    offset: float = field(default=0.0, metadata={"min": -100.0, "max": 100.0, "doc": "radians"})
    amplitude: float = field(default=0.0, metadata={"min": 0.0, "max": 100.0, "doc": "radians"})
    period: float = field(default=10.0, metadata={"min": 0.01, "max": 86400.0, "doc": "seconds"})
    phase: float = field(default=0.0, metadata={"min": -100.0, "max": 100.0, "doc": "radians"})
    keyframes: tuple[tuple[float, float], ...] = field(
        default=(),
        metadata={"min": -86400.0, "max": 86400.0, "doc": "[[t, angle], ...] with increasing t"},
    )
    loop: bool = field(default=False, metadata={"doc": "repeat the keyframes"})

    def __post_init__(self) -> None:
        if self.keyframes:
            if self.amplitude or self.offset:
                raise ValueError("give either keyframes or offset/amplitude, not both")
            times = [k[0] for k in self.keyframes]
            if any(b <= a for a, b in itertools.pairwise(times)) or times[0] < 0:
                raise ValueError("keyframe times must start at 0 or later and increase")
            if self.loop and times[-1] <= 0:
                raise ValueError("looped keyframes need a last time above 0")

    def angle(self, t: float) -> float:
        """The joint angle at scene time ``t``."""
        if not self.keyframes:
            return self.offset + self.amplitude * math.sin(
                2 * math.pi * t / self.period + self.phase
            )
        times = [k[0] for k in self.keyframes]
        if self.loop:
            t = t % times[-1]
        return float(np.interp(t, times, [k[1] for k in self.keyframes]))

    def bounds(self) -> tuple[float, float]:
        """The smallest and largest angle the motion reaches."""
        if self.keyframes:
            angles = [k[1] for k in self.keyframes]
            return min(angles), max(angles)
        return self.offset - self.amplitude, self.offset + self.amplitude


@dataclass(frozen=True)
class Perturbation:
    """How the simulated robot differs from its profile, on purpose (to measure what head
    calibration recovers): the rendered camera sits ``camera_offset`` (metres) and
    ``camera_rotation`` (roll, pitch, yaw, radians) off its profile mounting, both in the
    profile's camera frame (x along the optical axis, y left, z up); each joint named in
    ``joint_zero`` reads that many radians more than it stands at (a servo horn mounted off its
    zero); the joint readings of the joints the scene moves arrive ``delay`` seconds late."""

    camera_offset: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata={"min": -0.2, "max": 0.2, "doc": "camera off its mounting: x, y, z (m)"},
    )
    camera_rotation: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata={"min": -0.5, "max": 0.5, "doc": "camera turned on its mounting: rpy (rad)"},
    )
    joint_zero: dict[str, float] = field(
        default_factory=dict,
        metadata={"min": -0.5, "max": 0.5, "doc": "reading minus true angle per joint (rad)"},
    )
    delay: float = field(
        default=0.0,
        metadata={"min": 0.0, "max": 1.0, "doc": "seconds joint readings arrive late"},
    )

    def mounting(self) -> np.ndarray:
        """The 4x4 transform profile camera <- rendered camera."""
        return transform(self.camera_offset, self.camera_rotation)


@dataclass(frozen=True)
class SimRobot:
    """A robot standing in the scene: its platform profile, where it stands, how its joints move
    (joints not named stay at 0)."""

    name: str = field(metadata={"doc": "robot name, as in the experiment file"})
    profile: Path = field(metadata={"doc": "platform profile, relative to this file"})
    pose: GroundPose = field(
        default=(0.0, 0.0, 0.0),
        metadata={"min": -1000.0, "max": 1000.0, "doc": "x, y (m), yaw (rad)"},
    )
    joints: dict[str, JointMotion] = field(
        default_factory=dict, metadata={"doc": "motion per joint name"}
    )
    color: Color = field(
        default=(70, 72, 80), metadata={"min": 0, "max": 255, "doc": "colour of its body"}
    )
    perturb: Perturbation = field(
        default_factory=Perturbation,
        metadata={"doc": "how the simulated robot differs from its profile (calibration tests)"},
    )

    def __post_init__(self) -> None:
        if not _NAME.match(self.name):
            raise ValueError(f"robot name {self.name!r} may hold only letters, digits, - and _")

    def angles(self, t: float) -> dict[str, float]:
        """The angles of the moving joints at scene time ``t``."""
        return {name: motion.angle(t) for name, motion in self.joints.items()}


@dataclass(frozen=True)
class SimObject:
    """A thing on the floor the robots should find: block, cuboid, cylinder, cone, ball or toy
    (a small teddy-like figure made of several parts); or a ``figure``, a person walking
    through (a capsule), which is no object to find and is left out of the ground truth."""

    id: int = field(metadata={"min": 1, "max": 9999, "doc": "track id in the ground truth"})
    shape: Shape = field(
        metadata={"doc": "block, cuboid, cylinder, cone, ball, toy or figure (a person)"}
    )
    size: Vec3 = field(metadata={"min": 0.005, "max": 2.0, "doc": "bounding box: x, y, height (m)"})
    color: Color = field(metadata={"min": 0, "max": 255, "doc": "RGB"})
    pose: GroundPose = field(
        default=(0.0, 0.0, 0.0),
        metadata={"min": -1000.0, "max": 1000.0, "doc": "x, y (m), yaw (rad)"},
    )
    name: str = field(default="", metadata={"doc": "free text, e.g. red-block"})
    present: bool = field(default=True, metadata={"doc": "there at the start (else added later)"})

    def __post_init__(self) -> None:
        sx, sy, sz = self.size
        if self.shape in ROUND_SHAPES and not math.isclose(sx, sy):
            raise ValueError(f"a {self.shape} is round: size x and y (diameter) must be equal")
        if self.shape == "ball" and not (math.isclose(sx, sy) and math.isclose(sx, sz)):
            raise ValueError("a ball's size must be the same in x, y and height")
        if self.shape == "figure" and sz < sx:
            raise ValueError("a figure (a capsule) must be at least as tall as it is wide")

    @property
    def is_figure(self) -> bool:
        """A person walking through, not an object to perceive."""
        return self.shape == "figure"

    @property
    def label(self) -> str:
        return self.name or f"{self.shape}-{self.id}"


@dataclass(frozen=True)
class SimMarker:
    """A printed marker on a box face, as in the experiment's landmark boxes: ``side`` is the
    black square's side; it is printed on white paper with a quiet zone of ``side / 4`` around
    it. ``offset`` (right, up, seen from outside) moves it from the face centre; ``roll`` turns
    it counter-clockwise in the face plane."""

    id: int = field(metadata={"min": 0, "max": 100000, "doc": "marker id in the dictionary"})
    side: float = field(
        metadata={"min": 0.005, "max": 2.0, "doc": "side of the black square, metres"}
    )
    face: Face = field(default="front", metadata={"doc": "box face the marker is on"})
    offset: tuple[float, float] = field(
        default=(0.0, 0.0),
        metadata={"min": -10.0, "max": 10.0, "doc": "centre from the face centre: right, up (m)"},
    )
    roll: float = field(
        default=0.0,
        metadata={"min": -100.0, "max": 100.0, "doc": "turn in the face plane, radians"},
    )

    @property
    def paper(self) -> float:
        """Side of the white paper the marker is printed on."""
        return 1.5 * self.side


@dataclass(frozen=True)
class SimBox:
    """A carton box with markers on its side faces, standing still."""

    id: int = field(metadata={"min": 0, "max": 100000, "doc": "box id"})
    size: Vec3 = field(
        metadata={"min": 0.01, "max": 5.0, "doc": "length (front-back), width, height, metres"}
    )
    markers: tuple[SimMarker, ...] = field(metadata={"doc": "markers on the box"})
    pose: GroundPose = field(
        default=(0.0, 0.0, 0.0),
        metadata={"min": -1000.0, "max": 1000.0, "doc": "x, y (m), yaw (rad)"},
    )
    color: Color = field(
        default=(181, 139, 92), metadata={"min": 0, "max": 255, "doc": "cardboard colour"}
    )

    def __post_init__(self) -> None:
        length, width, height = self.size
        for m in self.markers:
            face_width = width if m.face in ("front", "back") else length
            right, up = m.offset
            half = m.paper / 2
            if abs(right) + half > face_width / 2 + 1e-9 or abs(up) + half > height / 2 + 1e-9:
                raise ValueError(
                    f"marker {m.id} with its paper ({m.paper:.3f} m) does not fit on the "
                    f"{m.face} face of box {self.id}"
                )


@dataclass(frozen=True)
class FloorMarker:
    """A marker printed on a sheet lying flat on the floor (the bring-up check's marker): its
    centre ``at`` (x, y), its top edge towards ``heading`` (world frame); printed with a quiet
    zone of ``side / 4`` around it like a box's markers."""

    id: int = field(metadata={"min": 0, "max": 100000, "doc": "marker id in the dictionary"})
    side: float = field(
        metadata={"min": 0.005, "max": 2.0, "doc": "side of the black square, metres"}
    )
    at: tuple[float, float] = field(
        default=(0.0, 0.0), metadata={"min": -1000.0, "max": 1000.0, "doc": "centre x, y (m)"}
    )
    heading: float = field(
        default=0.0,
        metadata={"min": -100.0, "max": 100.0, "doc": "direction its top edge faces, radians"},
    )

    def matrix(self) -> np.ndarray:
        """The 4x4 transform world <- marker (x right, y to its top edge, z up)."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        T = np.eye(4)
        T[:3, 0], T[:3, 1] = (s, -c, 0.0), (c, s, 0.0)
        T[:3, 2], T[:3, 3] = (0.0, 0.0, 1.0), (*self.at, 0.0)
        return T


@dataclass(frozen=True)
class Event:
    """One thing the experimenter does at time ``t``.

    - ``add``: ``object`` appears, at ``at`` (x, y) if given, else where it was (or its pose);
    - ``remove``: ``object`` disappears;
    - ``move``: ``object`` slides along ``path`` ([[x, y], ...]) in ``duration`` seconds;
    - ``lay_down``: a standing ``object`` is knocked over towards world heading ``direction``;
    - ``in_front``: ``object`` moves between ``target`` and robot ``robot``, ``distance`` from
      the target's centre (default: just clear of it), hiding the target from that robot;
    - ``lights``: every lamp's diffuse light and the ambient light go to ``scale`` times the
      scene's, in a linear ramp of ``duration`` seconds (none or 0: switched at once);
    - ``exposure``: every camera's exposure goes to ``scale`` times its first, the same way;
    - ``lights`` with ``lamp``: only that lamp (its index in ``lighting.lights``) changes, the
      other lamps and the ambient light stay (an uneven change);
    - ``white_balance``: every camera's red, green and blue gains go to ``gains`` times their
      first, the same way (a white-balance step or drift).
    """

    t: float = field(metadata={"min": 0.0, "max": 86400.0, "doc": "scene time, seconds"})
    action: Action = field(
        metadata={"doc": "add, remove, move, lay_down, in_front, lights, exposure or white_balance"}
    )
    object: int | None = field(
        default=None,
        metadata={"min": 0, "max": 1_000_000, "doc": "object id (not for lights, exposure)"},
    )
    at: tuple[float, float] | None = field(
        default=None, metadata={"min": -1000.0, "max": 1000.0, "doc": "add: x, y"}
    )
    path: tuple[tuple[float, float], ...] = field(
        default=(),
        metadata={"min": -1000.0, "max": 1000.0, "doc": "move: way points [[x, y], ...]"},
    )
    duration: float | None = field(
        default=None, metadata={"min": 0.0, "max": 86400.0, "doc": "seconds the action takes"}
    )
    scale: float | None = field(
        default=None,
        metadata={"min": 0.0, "max": 100.0, "doc": "lights, exposure: multiple of the start"},
    )
    direction: float = field(
        default=0.0, metadata={"min": -100.0, "max": 100.0, "doc": "lay_down: heading of the fall"}
    )
    target: int | None = field(
        default=None, metadata={"min": 0, "max": 1_000_000, "doc": "in_front: object to hide"}
    )
    robot: str | None = field(default=None, metadata={"doc": "in_front: robot it is hidden from"})
    distance: float | None = field(
        default=None,
        metadata={"min": 0.0, "max": 1000.0, "doc": "in_front: metres from the target's centre"},
    )
    lamp: int | None = field(
        default=None,
        metadata={"min": 0, "max": 1000, "doc": "lights: only this lamp (index), not all"},
    )
    gains: tuple[float, float, float] | None = field(
        default=None,
        metadata={"min": 0.0, "max": 100.0, "doc": "white_balance: R, G, B multiples of the start"},
    )

    def __post_init__(self) -> None:
        used = {
            "at": self.at is not None,
            "path": bool(self.path),
            "duration": self.duration is not None,
            "direction": self.direction != 0.0,
            "target": self.target is not None,
            "robot": self.robot is not None,
            "distance": self.distance is not None,
            "scale": self.scale is not None,
            "lamp": self.lamp is not None,
            "gains": self.gains is not None,
        }
        allowed = {
            "add": {"at"},
            "remove": set(),
            "move": {"path", "duration"},
            "lay_down": {"direction", "duration"},
            "in_front": {"target", "robot", "distance", "duration"},
            "lights": {"scale", "duration", "lamp"},
            "exposure": {"scale", "duration"},
            "white_balance": {"gains", "duration"},
        }[self.action]
        extra = sorted(k for k, v in used.items() if v and k not in allowed)
        if extra:
            raise ValueError(f"{self.action} does not take {', '.join(extra)}")
        if self.action in LIGHT_ACTIONS:
            if self.object is not None:
                raise ValueError(f"{self.action} acts on no object")
            if self.action == "white_balance":
                if self.gains is None:
                    raise ValueError("white_balance needs gains")
            elif self.scale is None:
                raise ValueError(f"{self.action} needs a scale")
            return
        if self.object is None:
            raise ValueError(f"{self.action} needs an object")
        if self.duration == 0.0:
            raise ValueError(f"{self.action} takes a duration above 0")
        if self.action == "move" and not self.path:
            raise ValueError("move needs a path")
        if self.action == "in_front" and (self.target is None or self.robot is None):
            raise ValueError("in_front needs a target and a robot")

    @property
    def span(self) -> float:
        """Seconds the action takes (0 for add and remove)."""
        if self.duration is not None:
            return self.duration
        return DEFAULT_DURATION.get(self.action, 0.0)


@dataclass(frozen=True)
class Scene:
    """A whole scene: floor, light, robots, objects, boxes and the experimenter's timeline."""

    name: str = field(metadata={"doc": "scene name"})
    robots: tuple[SimRobot, ...] = field(metadata={"doc": "robots in the scene"})
    description: str = field(default="", metadata={"doc": "free text"})
    seed: int = field(
        default=0, metadata={"min": 0, "max": 2**32 - 1, "doc": "seeds textures and camera noise"}
    )
    duration: float = field(
        default=20.0,
        metadata={"min": 0.0, "max": 86400.0, "doc": "seconds percept sim runs by default"},
    )
    calibration: float = field(
        default=0.0,
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "seconds at the start for the background calibration (percept sim writes "
            "their frames into the folder for percept track); 0: not said",
        },
    )
    marker_dictionary: str = field(
        default="DICT_APRILTAG_36h11", metadata={"doc": "cv2.aruco predefined dictionary"}
    )
    floor: Floor = field(default_factory=Floor, metadata={"doc": "the floor"})
    lighting: Lighting = field(default_factory=Lighting, metadata={"doc": "lights"})
    camera: CameraEffects = field(
        default_factory=CameraEffects, metadata={"doc": "noise and flicker of every camera"}
    )
    objects: tuple[SimObject, ...] = field(default=(), metadata={"doc": "objects"})
    boxes: tuple[SimBox, ...] = field(default=(), metadata={"doc": "carton boxes with markers"})
    floor_markers: tuple[FloorMarker, ...] = field(
        default=(), metadata={"doc": "markers lying flat on the floor"}
    )
    timeline: tuple[Event, ...] = field(default=(), metadata={"doc": "what the experimenter does"})

    def __post_init__(self) -> None:
        if not 1 <= len(self.robots) <= MAX_ROBOTS:
            raise ValueError(f"a scene holds 1 to {MAX_ROBOTS} robots, got {len(self.robots)}")
        for what, ids in (
            ("robot name", [r.name for r in self.robots]),
            ("object id", [o.id for o in self.objects]),
            ("box id", [b.id for b in self.boxes]),
            (
                "marker id",
                [m.id for b in self.boxes for m in b.markers] + [m.id for m in self.floor_markers],
            ),
        ):
            dupes = sorted(str(i) for i, n in Counter(ids).items() if n > 1)
            if dupes:
                raise ValueError(f"duplicate {what}: {', '.join(dupes)}")
        objects = {o.id for o in self.objects}
        robots = {r.name for r in self.robots}
        for i, e in enumerate(self.timeline):
            for ref in (e.object, e.target):
                if ref is not None and ref not in objects:
                    raise ValueError(f"timeline[{i}]: no object with id {ref}")
            if e.robot is not None and e.robot not in robots:
                raise ValueError(f"timeline[{i}]: no robot named {e.robot!r}")
            if e.lamp is not None and e.lamp >= len(self.lighting.lights):
                raise ValueError(
                    f"timeline[{i}]: no lamp {e.lamp} (lighting.lights has "
                    f"{len(self.lighting.lights)})"
                )
        from percept.drivers.sim.timeline import compile_timeline

        compile_timeline(self)  # raises for events that cannot happen (e.g. moving a removed one)

    def robot(self, name: str) -> SimRobot:
        """The robot called ``name``."""
        for r in self.robots:
            if r.name == name:
                return r
        known = ", ".join(r.name for r in self.robots)
        raise KeyError(f"scene {self.name!r} has no robot {name!r} (it has {known})")
