"""The messages robots and tools trade over Zenoh (SPEC §4.8), and their validation.

Every payload is UTF-8 JSON, at most :data:`MAX_PAYLOAD` bytes, whose ``schema`` field names
what it is and its version (``percept.boxes/1``). :func:`decode` turns bytes into one of the
message classes below or raises :class:`MessageError`, and nothing else, whatever the bytes:
a bad message must be countable, never fatal. Fields beyond the contract are ignored on receipt
(so senders may add fields freely) and numbers are checked for type and range.

Frames: positions are metres in the sender's ground frame, angles radians, ``stamp`` wall-clock
seconds (``time.time()``).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

from percept.perception.landmarks.records import BoxPose

MAX_PAYLOAD = 256 * 1024
MAX_BOXES = 256
MAX_OBJECTS = 1024
MAX_FAULTS = 64
SIGNALS = ("agree", "disagree", "success", "failure", "start")

_NAME = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_GAME = re.compile(r"^[A-Za-z0-9_.:-]{1,64}$")
_LIMIT = 1e12  # any number beyond this is garbage whatever it means
_POSITION = 1e4  # metres
_ANGLE = 4 * math.pi

ObjectId = str | int


class MessageError(ValueError):
    """A payload that is not a valid percept message: the one error :func:`decode` raises."""


def _fail(where: str, problem: str) -> MessageError:
    return MessageError(f"{where}: {problem}")


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _table(data: Any, where: str) -> Mapping[str, Any]:
    if not isinstance(data, dict):
        raise _fail(where, f"expected an object, got {_show(data)}")
    return data


def _get(data: Mapping[str, Any], key: str, where: str) -> Any:
    if key not in data:
        raise _fail(where, f"missing {key!r}")
    return data[key]


def _number(value: Any, where: str, lo: float = -_LIMIT, hi: float = _LIMIT) -> float:
    # Compare before float(): a huge JSON integer would overflow the conversion.
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _fail(where, f"expected a number, got {_show(value)}")
    if not lo <= value <= hi:
        raise _fail(where, f"expected a number in [{lo:g}, {hi:g}], got {_show(value)}")
    return float(value)


def _integer(value: Any, where: str, lo: int = 0, hi: int = 2**53) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise _fail(where, f"expected an integer, got {_show(value)}")
    if not lo <= value <= hi:
        raise _fail(where, f"expected an integer in [{lo}, {hi}], got {_show(value)}")
    return value


def _boolean(value: Any, where: str) -> bool:
    if not isinstance(value, bool):
        raise _fail(where, f"expected true or false, got {_show(value)}")
    return value


def _text(value: Any, where: str, pattern: re.Pattern[str] | None = None, most: int = 256) -> str:
    if not isinstance(value, str) or len(value) > most:
        raise _fail(where, f"expected a string of at most {most} characters, got {_show(value)}")
    if pattern is not None and not pattern.match(value):
        raise _fail(where, f"{value!r} does not match {pattern.pattern}")
    return value


def _list(value: Any, where: str, most: int) -> list[Any]:
    if not isinstance(value, list):
        raise _fail(where, f"expected a list, got {_show(value)}")
    if len(value) > most:
        raise _fail(where, f"expected at most {most} items, got {len(value)}")
    return value


def _object_id(value: Any, where: str) -> ObjectId:
    if isinstance(value, str):
        return _text(value, where, _GAME)
    return _integer(value, where, -(2**53), 2**53)


def _maybe(value: Any, where: str, read: Callable[[Any, str], Any]) -> Any:
    return None if value is None else read(value, where)


def _stamp(data: Mapping[str, Any], where: str) -> float:
    return _number(_get(data, "stamp", where), f"{where}.stamp", 0.0, 1e11)


def _robot(data: Mapping[str, Any], key: str, where: str) -> str:
    return _text(_get(data, key, where), f"{where}.{key}", _NAME)


def _box(value: Any, where: str) -> BoxPose:
    d = _table(value, where)
    return BoxPose(
        id=_integer(_get(d, "id", where), f"{where}.id", 0, 10**9),
        x=_number(_get(d, "x", where), f"{where}.x", -_POSITION, _POSITION),
        y=_number(_get(d, "y", where), f"{where}.y", -_POSITION, _POSITION),
        theta=_number(_get(d, "theta", where), f"{where}.theta", -_ANGLE, _ANGLE),
        n=_integer(d.get("n", 1), f"{where}.n", 0, 10**9),
    )


def _boxes(data: Mapping[str, Any], where: str) -> tuple[BoxPose, ...]:
    items = _list(_get(data, "boxes", where), f"{where}.boxes", MAX_BOXES)
    return tuple(_box(b, f"{where}.boxes[{i}]") for i, b in enumerate(items))


@dataclass(frozen=True)
class Boxes:
    """``percept.boxes/1``: the box poses a robot sees, in its ground frame, five times a
    second."""

    SCHEMA: ClassVar[str] = "percept.boxes/1"
    robot: str
    stamp: float
    boxes: tuple[BoxPose, ...]

    def to_json(self) -> dict[str, Any]:
        return {
            "robot": self.robot,
            "stamp": self.stamp,
            "boxes": [b.as_dict() for b in self.boxes],
        }

    @classmethod
    def from_json(cls, d: Mapping[str, Any], where: str) -> Boxes:
        return cls(_robot(d, "robot", where), _stamp(d, where), _boxes(d, where))


@dataclass(frozen=True)
class PeerPose:
    """Where a peer robot stands in my ground frame (``x``, ``y``, ``theta``), estimated at
    wall-clock ``stamp`` from ``n_boxes`` boxes both of us see."""

    x: float
    y: float
    theta: float
    stamp: float
    n_boxes: int

    def as_dict(self) -> dict[str, float | int]:
        return {
            "x": self.x,
            "y": self.y,
            "theta": self.theta,
            "stamp": self.stamp,
            "n_boxes": self.n_boxes,
        }

    @classmethod
    def from_json(cls, value: Any, where: str) -> PeerPose:
        d = _table(value, where)
        return cls(
            x=_number(_get(d, "x", where), f"{where}.x", -_POSITION, _POSITION),
            y=_number(_get(d, "y", where), f"{where}.y", -_POSITION, _POSITION),
            theta=_number(_get(d, "theta", where), f"{where}.theta", -_ANGLE, _ANGLE),
            stamp=_stamp(d, where),
            n_boxes=_integer(_get(d, "n_boxes", where), f"{where}.n_boxes", 0, MAX_BOXES),
        )


def _peers(value: Any, where: str) -> dict[str, PeerPose]:
    d = _table(value, where)
    if len(d) > MAX_BOXES:
        raise _fail(where, f"expected at most {MAX_BOXES} peers, got {len(d)}")
    return {
        _text(name, f"{where} key", _NAME): PeerPose.from_json(pose, f"{where}.{name}")
        for name, pose in d.items()
    }


def _features(value: Any, where: str) -> dict[str, float | None]:
    """Feature values by name; a value may be null (no ground position above the horizon)."""
    d = _table(value, where)
    if len(d) > 64:
        raise _fail(where, f"expected at most 64 features, got {len(d)}")
    return {
        _text(k, f"{where} key", most=64): _maybe(v, f"{where}.{k}", _number) for k, v in d.items()
    }


@dataclass(frozen=True)
class WorldObject:
    """One anchored object of a world model: its anchor id, image box ``[left, top, width,
    height]`` (pixels), the seven features and their scaled values (null where undefined)."""

    id: ObjectId
    bbox: tuple[float, float, float, float]
    features: dict[str, float | None]
    scaled: dict[str, float | None] = field(default_factory=dict)
    on_ground: bool = True
    age: float = 0.0
    in_motion: bool = False

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "bbox": list(self.bbox),
            "features": dict(self.features),
            "scaled": dict(self.scaled),
            "on_ground": self.on_ground,
            "age": self.age,
            "in_motion": self.in_motion,
        }

    @property
    def position(self) -> tuple[float, float] | None:
        """``(x, y)`` on the ground, or None when the object has no ground position."""
        x, y = self.features.get("x"), self.features.get("y")
        if not self.on_ground or x is None or y is None:
            return None
        return x, y

    @classmethod
    def from_json(cls, value: Any, where: str) -> WorldObject:
        d = _table(value, where)
        bbox = _list(_get(d, "bbox", where), f"{where}.bbox", 4)
        if len(bbox) != 4:
            raise _fail(f"{where}.bbox", f"expected 4 numbers, got {len(bbox)}")
        return cls(
            id=_object_id(_get(d, "id", where), f"{where}.id"),
            bbox=tuple(_number(v, f"{where}.bbox[{i}]") for i, v in enumerate(bbox)),  # type: ignore[arg-type]
            features=_features(_get(d, "features", where), f"{where}.features"),
            scaled=_features(d.get("scaled", {}), f"{where}.scaled"),
            on_ground=_boolean(d.get("on_ground", True), f"{where}.on_ground"),
            age=_number(d.get("age", 0.0), f"{where}.age", 0.0),
            in_motion=_boolean(d.get("in_motion", False), f"{where}.in_motion"),
        )


def _camera(value: Any, where: str) -> dict[str, Any]:
    d = _table(value, where)
    rows = _list(_get(d, "R", where), f"{where}.R", 3)
    t = _list(_get(d, "t", where), f"{where}.t", 3)
    if len(rows) != 3 or len(t) != 3:
        raise _fail(where, "expected R as 3 rows of 3 numbers and t as 3 numbers")
    R = [
        [_number(v, f"{where}.R[{i}][{j}]", -1.01, 1.01) for j, v in enumerate(_row(r, i, where))]
        for i, r in enumerate(rows)
    ]
    out = {
        "R": R,
        "t": [_number(v, f"{where}.t[{i}]", -_POSITION, _POSITION) for i, v in enumerate(t)],
    }
    if "frame" in d:  # the parent frame's name, "ground"
        out["frame"] = _text(d["frame"], f"{where}.frame", _NAME)
    return out


def _row(value: Any, i: int, where: str) -> list[Any]:
    row = _list(value, f"{where}.R[{i}]", 3)
    if len(row) != 3:
        raise _fail(f"{where}.R[{i}]", f"expected 3 numbers, got {len(row)}")
    return row


@dataclass(frozen=True)
class World:
    """``percept.world/1``: one robot's world model after a frame: its camera pose, anchored
    objects, boxes and the peers it has located. Beyond the contract: ``t``, the frame's
    monotonic time in the sender's process (null when unknown), and ``pose_fresh``, false when
    the joint readings behind the camera pose were too old."""

    SCHEMA: ClassVar[str] = "percept.world/1"
    robot: str
    stamp: float
    frame: int
    camera: dict[str, Any]
    objects: tuple[WorldObject, ...]
    boxes: tuple[BoxPose, ...] = ()
    peers: dict[str, PeerPose] = field(default_factory=dict)
    t: float | None = None
    pose_fresh: bool = True

    def to_json(self) -> dict[str, Any]:
        return {
            "robot": self.robot,
            "stamp": self.stamp,
            "t": self.t,
            "frame": self.frame,
            "camera": self.camera,
            "pose_fresh": self.pose_fresh,
            "objects": [o.to_json() for o in self.objects],
            "boxes": [b.as_dict() for b in self.boxes],
            "peers": {name: p.as_dict() for name, p in self.peers.items()},
        }

    @classmethod
    def from_json(cls, d: Mapping[str, Any], where: str) -> World:
        objects = _list(_get(d, "objects", where), f"{where}.objects", MAX_OBJECTS)
        return cls(
            robot=_robot(d, "robot", where),
            stamp=_stamp(d, where),
            frame=_integer(_get(d, "frame", where), f"{where}.frame"),
            camera=_camera(_get(d, "camera", where), f"{where}.camera"),
            objects=tuple(
                WorldObject.from_json(o, f"{where}.objects[{i}]") for i, o in enumerate(objects)
            ),
            boxes=_boxes(d, where) if "boxes" in d else (),
            peers=_peers(d.get("peers", {}), f"{where}.peers"),
            t=_maybe(d.get("t"), f"{where}.t", _number),
            pose_fresh=_boolean(d.get("pose_fresh", True), f"{where}.pose_fresh"),
        )


@dataclass(frozen=True)
class Status:
    """``percept.status/1``: how a robot's daemon is doing, about once a second. ``camera``,
    ``servos`` and ``peers`` are free-form JSON (their size is bounded by the payload's).

    Beyond the contract, what ``percept run`` also reports: the median milliseconds per frame,
    frames processed, frames with too old or no joint readings, the background model's state,
    peer messages dropped by a full inbox, the pointing games (``played``, ``success``,
    ``as_speaker``), CPU use (cores), resident memory (MB), the recording's state (free-form,
    null when not recording) and gaze (free-form: ``enabled``, ``state``, ``target``...)."""

    SCHEMA: ClassVar[str] = "percept.status/1"
    robot: str
    stamp: float
    fps: float
    dropped_frames: int
    camera: Any
    servos: Any
    peers: Any
    rejected_messages: int
    faults: tuple[str, ...]
    ms_per_frame: float | None = None
    frames: int = 0
    old_joint_frames: int = 0
    frames_without_joints: int = 0
    background: str = ""
    inbox_dropped: int = 0
    games: dict[str, int] = field(default_factory=dict)
    cpu: float | None = None
    rss_mb: float | None = None
    recording: Any = None
    gaze: Any = None

    def to_json(self) -> dict[str, Any]:
        return {
            "robot": self.robot,
            "stamp": self.stamp,
            "fps": self.fps,
            "ms_per_frame": self.ms_per_frame,
            "frames": self.frames,
            "dropped_frames": self.dropped_frames,
            "old_joint_frames": self.old_joint_frames,
            "frames_without_joints": self.frames_without_joints,
            "camera": self.camera,
            "servos": self.servos,
            "background": self.background,
            "peers": self.peers,
            "rejected_messages": self.rejected_messages,
            "inbox_dropped": self.inbox_dropped,
            "games": dict(self.games),
            "cpu": self.cpu,
            "rss_mb": self.rss_mb,
            "recording": self.recording,
            "gaze": self.gaze,
            "faults": list(self.faults),
        }

    @classmethod
    def from_json(cls, d: Mapping[str, Any], where: str) -> Status:
        faults = _list(_get(d, "faults", where), f"{where}.faults", MAX_FAULTS)

        def count(key: str) -> int:
            return _integer(d.get(key, 0), f"{where}.{key}")

        return cls(
            robot=_robot(d, "robot", where),
            stamp=_stamp(d, where),
            fps=_number(_get(d, "fps", where), f"{where}.fps", 0.0, 1e6),
            dropped_frames=_integer(_get(d, "dropped_frames", where), f"{where}.dropped_frames"),
            camera=_get(d, "camera", where),
            servos=_get(d, "servos", where),
            peers=_get(d, "peers", where),
            rejected_messages=_integer(
                _get(d, "rejected_messages", where), f"{where}.rejected_messages"
            ),
            faults=tuple(_text(f, f"{where}.faults[{i}]", most=1024) for i, f in enumerate(faults)),
            ms_per_frame=_maybe(
                d.get("ms_per_frame"), f"{where}.ms_per_frame", lambda v, w: _number(v, w, 0.0)
            ),
            frames=count("frames"),
            old_joint_frames=count("old_joint_frames"),
            frames_without_joints=count("frames_without_joints"),
            background=_text(d.get("background", ""), f"{where}.background"),
            inbox_dropped=count("inbox_dropped"),
            games=_counts(d.get("games", {}), f"{where}.games"),
            cpu=_maybe(d.get("cpu"), f"{where}.cpu", lambda v, w: _number(v, w, 0.0, 1024.0)),
            rss_mb=_maybe(d.get("rss_mb"), f"{where}.rss_mb", lambda v, w: _number(v, w, 0.0)),
            recording=d.get("recording"),
            gaze=d.get("gaze"),
        )


def _counts(value: Any, where: str) -> dict[str, int]:
    """A small table of named counts (``{"played": 3, "success": 2}``)."""
    d = _table(value, where)
    if len(d) > 64:
        raise _fail(where, f"expected at most 64 counts, got {len(d)}")
    return {_text(k, f"{where} key", most=64): _integer(v, f"{where}.{k}") for k, v in d.items()}


def _exchange(d: Mapping[str, Any], where: str) -> tuple[str, str, str]:
    """``game``, ``from`` and ``to`` of a pointing or signal message."""
    return (
        _text(_get(d, "game", where), f"{where}.game", _GAME),
        _robot(d, "from", where),
        _robot(d, "to", where),
    )


@dataclass(frozen=True)
class PointingRequest:
    """``percept.pointing/1`` from the speaker: the topic is at ``(x, y)`` in its frame."""

    SCHEMA: ClassVar[str] = "percept.pointing/1"
    game: str
    sender: str
    to: str
    x: float
    y: float

    def to_json(self) -> dict[str, Any]:
        return {"game": self.game, "from": self.sender, "to": self.to, "x": self.x, "y": self.y}


@dataclass(frozen=True)
class PointingAnswer:
    """``percept.pointing/1`` from the hearer: the anchor it chose (``object``, null for none)
    and, beyond the contract, that object's ``(x, y)`` in the hearer's frame, so the speaker can
    tell whether it is the same physical object."""

    SCHEMA: ClassVar[str] = "percept.pointing/1"
    game: str
    sender: str
    to: str
    object: ObjectId | None
    x: float | None = None
    y: float | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "game": self.game,
            "from": self.sender,
            "to": self.to,
            "object": self.object,
        }
        if self.x is not None and self.y is not None:
            out["x"], out["y"] = self.x, self.y
        return out


def _pointing(d: Mapping[str, Any], where: str) -> PointingRequest | PointingAnswer:
    game, sender, to = _exchange(d, where)
    if "object" in d:
        has_xy = "x" in d and "y" in d
        return PointingAnswer(
            game,
            sender,
            to,
            _maybe(d["object"], f"{where}.object", _object_id),
            _number(d["x"], f"{where}.x", -_POSITION, _POSITION) if has_xy else None,
            _number(d["y"], f"{where}.y", -_POSITION, _POSITION) if has_xy else None,
        )
    return PointingRequest(
        game,
        sender,
        to,
        _number(_get(d, "x", where), f"{where}.x", -_POSITION, _POSITION),
        _number(_get(d, "y", where), f"{where}.y", -_POSITION, _POSITION),
    )


@dataclass(frozen=True)
class Signal:
    """``percept.signal/1``: agree, disagree, success or failure in game ``game``; and, from
    the joint-attention monitor, ``start``, naming who speaks and who hears."""

    SCHEMA: ClassVar[str] = "percept.signal/1"
    game: str
    sender: str
    to: str
    signal: str
    speaker: str | None = None
    hearer: str | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "game": self.game,
            "from": self.sender,
            "to": self.to,
            "signal": self.signal,
        }
        if self.speaker is not None:
            out["speaker"] = self.speaker
        if self.hearer is not None:
            out["hearer"] = self.hearer
        return out

    @classmethod
    def from_json(cls, d: Mapping[str, Any], where: str) -> Signal:
        game, sender, to = _exchange(d, where)
        signal = _get(d, "signal", where)
        if signal not in SIGNALS:
            raise _fail(
                f"{where}.signal", f"expected one of {', '.join(SIGNALS)}, got {_show(signal)}"
            )
        return cls(
            game,
            sender,
            to,
            signal,
            _maybe(d.get("speaker"), f"{where}.speaker", _name),
            _maybe(d.get("hearer"), f"{where}.hearer", _name),
        )


def _name(value: Any, where: str) -> str:
    return _text(value, where, _NAME)


Message = Boxes | World | Status | PointingRequest | PointingAnswer | Signal

_READERS: dict[str, Callable[[Mapping[str, Any], str], Message]] = {
    Boxes.SCHEMA: Boxes.from_json,
    World.SCHEMA: World.from_json,
    Status.SCHEMA: Status.from_json,
    PointingRequest.SCHEMA: _pointing,
    Signal.SCHEMA: Signal.from_json,
}
SCHEMAS = tuple(_READERS)
#: The schema each key ``<prefix>/<robot>/<topic>`` carries.
TOPICS = {
    "world": World.SCHEMA,
    "boxes": Boxes.SCHEMA,
    "status": Status.SCHEMA,
    "pointing": PointingRequest.SCHEMA,
    "signal": Signal.SCHEMA,
}


def encode(message: Message) -> bytes:
    """The message as a compact UTF-8 JSON payload naming its schema."""
    body = {"schema": message.SCHEMA, **message.to_json()}
    try:
        payload = json.dumps(body, allow_nan=False, separators=(",", ":")).encode()
    except (TypeError, ValueError) as err:
        raise MessageError(f"{message.SCHEMA}: cannot encode: {err}") from None
    if len(payload) > MAX_PAYLOAD:
        raise MessageError(f"{message.SCHEMA}: {len(payload)} bytes, more than {MAX_PAYLOAD}")
    return payload


def sender(message: Message) -> str:
    """The robot (or program) that sent ``message``: ``robot`` or ``from``."""
    return message.robot if isinstance(message, Boxes | World | Status) else message.sender


def _no_constants(name: str) -> Any:
    raise MessageError(f"{name} is not a number JSON allows")


def decode(payload: bytes | bytearray | memoryview | str, expect: str | None = None) -> Message:
    """The message in ``payload``; ``expect`` is the schema the key carries (None: any).

    Raises :class:`MessageError` for anything that is not a valid message of that schema:
    oversized, not UTF-8, not JSON, not an object, an unknown or unexpected schema, a missing
    field, a wrong type or a number out of range.
    """
    try:
        raw = payload.encode() if isinstance(payload, str) else bytes(payload)
        if len(raw) > MAX_PAYLOAD:
            raise MessageError(f"payload of {len(raw)} bytes, more than {MAX_PAYLOAD}")
        data = json.loads(raw.decode("utf-8"), parse_constant=_no_constants)
        d = _table(data, "payload")
        schema = d.get("schema")
        if not isinstance(schema, str) or schema not in _READERS:
            raise _fail("payload", f"unknown schema {_show(schema)}")
        if expect is not None and schema != expect:
            raise _fail("payload", f"expected schema {expect}, got {schema}")
        return _READERS[schema](d, schema)
    except MessageError:
        raise
    except (ValueError, TypeError, RecursionError, OverflowError) as err:
        # Not UTF-8, not JSON, nested too deep, an integer too long to read: all just garbage.
        raise MessageError(f"not a JSON message: {type(err).__name__}: {err}") from None
