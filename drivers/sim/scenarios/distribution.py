"""A distribution of scenes (``config/scenarios/*.toml``): what a room may hold and what may
happen in it, for :mod:`percept.drivers.sim.scenarios.draw` to draw scenes from.

Every ``[lo, hi]`` pair is a range drawn uniformly; every ``p_*`` key is the chance (0-1) that a
scene has that thing. Lengths in metres, angles in radians, times in seconds, colours 8-bit RGB,
as in scene files (:mod:`percept.drivers.sim.scene`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from percept.drivers.sim.scene import Color, GroundPose, Shape

Range = tuple[float, float]
_SHAPES: tuple[Shape, ...] = ("block", "cuboid", "cylinder", "cone", "ball", "toy")


def _check_ranges(owner: object, *names: str) -> None:
    for name in names:
        lo, hi = getattr(owner, name)
        if lo > hi:
            raise ValueError(f"{name}: the low end {lo:g} is above the high end {hi:g}")


def _p(doc: str) -> dict[str, object]:
    return {"min": 0.0, "max": 1.0, "doc": doc}


@dataclass(frozen=True)
class RobotPlace:
    """A robot of every drawn scene."""

    name: str = field(metadata={"doc": "robot name"})
    profile: str = field(
        metadata={"doc": "platform profile: a shipped name, or a path relative to this file"}
    )
    pose: GroundPose = field(
        default=(0.0, 0.0, 0.0), metadata={"min": -1000.0, "max": 1000.0, "doc": "x, y, yaw"}
    )


@dataclass(frozen=True)
class SceneRange:
    """How long a scene is and how it starts."""

    duration: Range = field(
        default=(20.0, 45.0), metadata={"min": 1.0, "max": 3600.0, "doc": "seconds a scene lasts"}
    )
    calibration: float = field(
        default=2.0,
        metadata={
            "min": 0.1,
            "max": 600.0,
            "doc": "seconds of empty floor at the start while a still head calibrates",
        },
    )
    textures: tuple[str, ...] = field(
        default=("wood", "carpet", "tiles"), metadata={"doc": "floor textures drawn from"}
    )
    floor_colors: tuple[Color, ...] = field(
        default=((176, 134, 94), (128, 132, 118), (150, 150, 145)),
        metadata={"min": 0, "max": 255, "doc": "floor colours drawn from"},
    )

    def __post_init__(self) -> None:
        _check_ranges(self, "duration")
        if not self.textures or not self.floor_colors:
            raise ValueError("textures and floor_colors need at least one entry each")
        bad = sorted(set(self.textures) - {"wood", "carpet", "tiles"})
        if bad:
            raise ValueError(f"unknown texture(s) {', '.join(bad)}: wood, carpet or tiles")


@dataclass(frozen=True)
class ObjectRange:
    """The objects on the floor and what the experimenter does with them."""

    count: tuple[int, int] = field(
        default=(3, 10), metadata={"min": 1, "max": 40, "doc": "objects per scene"}
    )
    shapes: tuple[Shape, ...] = field(default=_SHAPES, metadata={"doc": "shapes drawn from"})
    size: Range = field(
        default=(0.03, 0.15),
        metadata={"min": 0.01, "max": 1.0, "doc": "every extent of an object, metres"},
    )
    area: float = field(
        default=0.3,
        metadata={"min": 0.05, "max": 10.0, "doc": "radius of the table area around (0, 0)"},
    )
    colors: tuple[Color, ...] = field(
        default=(
            (200, 30, 35),
            (30, 70, 200),
            (230, 200, 20),
            (40, 160, 60),
            (220, 90, 170),
            (240, 120, 20),
            (30, 180, 190),
            (130, 60, 170),
        ),
        metadata={"min": 0, "max": 255, "doc": "bright colours drawn from"},
    )
    p_dark: float = field(default=0.15, metadata=_p("an object is dark (value below 60)"))
    p_desaturated: float = field(default=0.15, metadata=_p("an object is greyish"))
    p_floor_like: float = field(default=0.1, metadata=_p("an object is near the floor's colour"))
    p_same_color: float = field(default=0.3, metadata=_p("two objects share a colour"))
    p_move: float = field(default=0.5, metadata=_p("an object is moved"))
    p_remove: float = field(default=0.4, metadata=_p("an object is taken away"))
    p_knock: float = field(default=0.3, metadata=_p("an object is knocked over"))
    p_hide: float = field(default=0.3, metadata=_p("an object is put in front of another"))

    def __post_init__(self) -> None:
        _check_ranges(self, "count", "size")
        if not self.shapes or not self.colors:
            raise ValueError("shapes and colors need at least one entry each")
        bad = sorted(set(self.shapes) - set(_SHAPES))
        if bad:
            raise ValueError(f"unknown shape(s) {', '.join(bad)}: {', '.join(_SHAPES)}")


@dataclass(frozen=True)
class LightRange:
    """Lamps, ambient light and how they and the cameras' exposure change."""

    lamps: tuple[int, int] = field(default=(1, 2), metadata={"min": 1, "max": 8, "doc": "lamps"})
    ambient: Range = field(default=(0.3, 0.5), metadata={"min": 0.0, "max": 1.0, "doc": "level"})
    diffuse: Range = field(
        default=(0.3, 0.6), metadata={"min": 0.0, "max": 1.0, "doc": "each lamp's level"}
    )
    p_drift: float = field(default=0.5, metadata=_p("the light drifts"))
    drift: Range = field(
        default=(0.0, 0.6), metadata={"min": 0.0, "max": 0.95, "doc": "fraction it drifts by"}
    )
    drift_seconds: Range = field(
        default=(10.0, 120.0), metadata={"min": 0.0, "max": 3600.0, "doc": "how long it drifts"}
    )
    p_brighter: float = field(default=0.3, metadata=_p("a drift goes up (by half as much)"))
    p_switch: float = field(default=0.3, metadata=_p("all light is switched down and back"))
    switch: Range = field(
        default=(0.4, 0.7), metadata={"min": 0.0, "max": 10.0, "doc": "level while switched"}
    )
    p_uneven: float = field(default=0.3, metadata=_p("one of two lamps alone changes"))
    uneven: Range = field(
        default=(0.0, 0.5), metadata={"min": 0.0, "max": 10.0, "doc": "that lamp's new level"}
    )
    p_exposure: float = field(default=0.3, metadata=_p("the exposure steps"))
    exposure: Range = field(
        default=(0.75, 1.3), metadata={"min": 0.05, "max": 10.0, "doc": "new exposure"}
    )
    p_white_balance: float = field(default=0.2, metadata=_p("the white balance steps"))
    white_balance: Range = field(
        default=(0.85, 1.15), metadata={"min": 0.05, "max": 10.0, "doc": "each channel's gain"}
    )
    p_flicker: float = field(default=0.4, metadata=_p("the exposure flickers"))
    flicker: Range = field(
        default=(0.01, 0.06), metadata={"min": 0.0, "max": 0.9, "doc": "relative amplitude"}
    )
    flicker_hz: tuple[float, ...] = field(
        default=(0.0, 1.7, 100.0),
        metadata={"min": 0.0, "max": 1000.0, "doc": "frequencies drawn from (0: random)"},
    )

    def __post_init__(self) -> None:
        _check_ranges(
            self,
            "lamps",
            "ambient",
            "diffuse",
            "drift",
            "drift_seconds",
            "switch",
            "uneven",
            "exposure",
            "white_balance",
            "flicker",
        )
        if not self.flicker_hz:
            raise ValueError("flicker_hz needs at least one entry")


@dataclass(frozen=True)
class HeadRange:
    """How the robots' heads move: ``still``, ``fixations`` (turns to points of the table and
    holds), ``sweep`` (pans back and forth) or ``gaze`` (quick looks at objects in turn, as the
    gaze does during games), drawn with these weights. A moving head calibrates while it sweeps
    its pan range over the empty floor."""

    still: float = field(default=0.4, metadata={"min": 0.0, "max": 1000.0, "doc": "weight"})
    fixations: float = field(default=0.2, metadata={"min": 0.0, "max": 1000.0, "doc": "weight"})
    sweep: float = field(default=0.2, metadata={"min": 0.0, "max": 1000.0, "doc": "weight"})
    gaze: float = field(default=0.2, metadata={"min": 0.0, "max": 1000.0, "doc": "weight"})
    tilt: Range = field(
        default=(-0.55, -0.45), metadata={"min": -1.5, "max": 1.5, "doc": "head tilt, radians"}
    )
    pan: float = field(
        default=0.75, metadata={"min": 0.0, "max": 1.5, "doc": "largest pan, radians"}
    )
    speed: Range = field(
        default=(0.3, 0.8), metadata={"min": 0.01, "max": 10.0, "doc": "pan speed, rad/s"}
    )

    def __post_init__(self) -> None:
        _check_ranges(self, "tilt", "speed")
        if self.still + self.fixations + self.sweep + self.gaze <= 0:
            raise ValueError("at least one head motion needs a weight above 0")


@dataclass(frozen=True)
class PeopleRange:
    """People: figures walking through, standing beside the table, present while the
    background calibrates; an arm reaching in to put an object down."""

    p_walk: float = field(default=0.5, metadata=_p("people walk through"))
    walkers: tuple[int, int] = field(
        default=(1, 2), metadata={"min": 0, "max": 10, "doc": "walks through per scene"}
    )
    p_stand: float = field(default=0.3, metadata=_p("a person stands beside the table"))
    stand_seconds: Range = field(
        default=(5.0, 20.0), metadata={"min": 0.0, "max": 3600.0, "doc": "how long"}
    )
    p_calibration: float = field(default=0.3, metadata=_p("a person is there while calibrating"))
    p_arm: float = field(default=0.4, metadata=_p("an arm reaches in to put objects down"))
    height: Range = field(
        default=(1.55, 1.85), metadata={"min": 0.5, "max": 2.5, "doc": "a person's height"}
    )
    colors: tuple[Color, ...] = field(
        default=((70, 80, 110), (150, 60, 50), (40, 40, 45), (200, 200, 190), (90, 110, 70)),
        metadata={"min": 0, "max": 255, "doc": "clothes drawn from"},
    )

    def __post_init__(self) -> None:
        _check_ranges(self, "walkers", "stand_seconds", "height")
        if not self.colors:
            raise ValueError("colors needs at least one entry")


@dataclass(frozen=True)
class CameraRange:
    """What the cameras add: noise, JPEG compression, motion blur while the head turns."""

    noise: Range = field(
        default=(0.5, 4.0), metadata={"min": 0.0, "max": 100.0, "doc": "pixel noise std dev"}
    )
    p_jpeg: float = field(default=0.6, metadata=_p("frames are JPEG-compressed"))
    jpeg_quality: tuple[int, int] = field(
        default=(60, 95), metadata={"min": 1, "max": 100, "doc": "JPEG quality"}
    )
    shutter: Range = field(
        default=(0.005, 0.03), metadata={"min": 0.0, "max": 1.0, "doc": "exposure time, s"}
    )

    def __post_init__(self) -> None:
        _check_ranges(self, "noise", "jpeg_quality", "shutter")


@dataclass(frozen=True)
class BoxRange:
    """The two marker boxes of the experiment, always in the scene, somewhere beyond the
    table area on the side facing the robots."""

    distance: Range = field(
        default=(0.4, 0.75),
        metadata={"min": 0.0, "max": 100.0, "doc": "metres from (0, 0) to a box's centre"},
    )
    bearing: Range = field(
        default=(0.5, 1.7),
        metadata={"min": -7.0, "max": 7.0, "doc": "direction from (0, 0), radians"},
    )

    def __post_init__(self) -> None:
        _check_ranges(self, "distance", "bearing")


@dataclass(frozen=True)
class Distribution:
    """A whole distribution of scenes (one file)."""

    name: str = field(metadata={"doc": "distribution name (prefix of the scene names)"})
    robots: tuple[RobotPlace, ...] = field(metadata={"doc": "the robots of every scene"})
    description: str = field(default="", metadata={"doc": "free text"})
    scene: SceneRange = field(default_factory=SceneRange, metadata={"doc": "length, floor"})
    objects: ObjectRange = field(default_factory=ObjectRange, metadata={"doc": "objects"})
    light: LightRange = field(default_factory=LightRange, metadata={"doc": "light"})
    heads: HeadRange = field(default_factory=HeadRange, metadata={"doc": "head motion"})
    people: PeopleRange = field(default_factory=PeopleRange, metadata={"doc": "people"})
    camera: CameraRange = field(default_factory=CameraRange, metadata={"doc": "camera"})
    boxes: BoxRange = field(default_factory=BoxRange, metadata={"doc": "marker boxes"})

    def __post_init__(self) -> None:
        if not self.robots:
            raise ValueError("a distribution needs at least one robot")
