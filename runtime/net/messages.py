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
from dataclasses import dataclass, field, replace
from typing import Annotated, ClassVar, NotRequired, Self, TypedDict, TypeVar

from percept.perception.landmarks.records import BoxPose
from percept.runtime.net.codec import (
    JSON,
    OMIT_NONE,
    Count,
    Fields,
    FreeJSON,
    Key,
    MessageError,
    Most,
    OneOf,
    Range,
    Size,
    Text,
    fail,
    read,
    show,
    write,
)
from percept.runtime.net.settings import ROBOT_NAME

MAX_PAYLOAD = 256 * 1024
MAX_BOXES = 256
MAX_OBJECTS = 1024
MAX_FAULTS = 64
MAX_TEXT = 256  # characters of a free-text field (a status's background, a sender's reason)
SIGNALS = ("agree", "disagree", "success", "failure", "start")
#: The games the joint-attention monitor starts (a start signal's ``play``).
GAMES = ("pointing", "guessing")
OUTCOMES = ("success", "failure")

_POSITION = 1e4  # metres
_ANGLE = 4 * math.pi

Name = Annotated[str, Text(ROBOT_NAME)]  # a robot or program
GameId = Annotated[str, Text(re.compile(r"[A-Za-z0-9_.:-]{1,64}"))]
Stamp = Annotated[float, Range(0.0, 1e11)]
Position = Annotated[float, Range(-_POSITION, _POSITION)]
Angle = Annotated[float, Range(-_ANGLE, _ANGLE)]
ObjectId = GameId | Annotated[int, Count(-(2**53), 2**53)]
_Natural = Annotated[int, Count(0, 10**9)]  # a box id or a count of sightings
Box = Annotated[BoxPose, Fields(id=_Natural, x=Position, y=Position, theta=Angle, n=_Natural)]
BoxList = Annotated[tuple[Box, ...], Most(MAX_BOXES)]
Label = Annotated[str, Text(most=64)]
Word = Annotated[str, Text(re.compile(r"[a-z]{1,64}"))]  # a word form of a language game
Game = Annotated[str, OneOf(GAMES)]
ObjectIds = Annotated[tuple[ObjectId, ...], Most(MAX_OBJECTS, "objects")]


def clip(text: str, most: int = MAX_TEXT) -> str:
    """``text`` in at most ``most`` characters: its middle cut to ``...`` if longer (a path's
    file name and a fault's reason are at the ends)."""
    if len(text) <= most:
        return text
    head = (most - 3) // 2
    return text[:head] + "..." + text[len(text) - (most - 3 - head) :]


#: Feature values by name; a value may be null (no ground position above the horizon).
Features = Annotated[dict[Label, float | None], Most(64, "features")]
#: A small table of named counts (``{"played": 3, "success": 2}``).
Counts = Annotated[dict[Label, int], Most(64, "counts")]
Shares = Annotated[dict[Label, Annotated[float, Range(0.0, 1024.0)]], Most(64, "threads")]


class _Json:
    """A message's JSON, derived from its fields' annotations (:mod:`.codec`)."""

    SCHEMA: ClassVar[str]

    def to_json(self) -> dict[str, JSON]:
        """The message's fields as JSON (without ``schema``), checked as on receipt."""
        return write(self, self.SCHEMA)

    @classmethod
    def from_json(cls, data: Mapping[str, JSON], where: str) -> Self:
        """The message in ``data``; raises :class:`MessageError` naming ``where``."""
        return read(cls, data, where)


@dataclass(frozen=True)
class Boxes(_Json):
    """``percept.boxes/1``: the box poses a robot sees, in its ground frame, five times a
    second."""

    SCHEMA: ClassVar[str] = "percept.boxes/1"
    robot: Name
    stamp: Stamp
    boxes: BoxList


@dataclass(frozen=True)
class PeerPose:
    """Where a peer robot stands in my ground frame (``x``, ``y``, ``theta``), estimated at
    wall-clock ``stamp`` from ``n_boxes`` boxes both of us see."""

    x: Position
    y: Position
    theta: Angle
    stamp: Stamp
    n_boxes: Annotated[int, Count(0, MAX_BOXES)]


@dataclass(frozen=True)
class WorldObject:
    """One anchored object of a world model: its anchor id, image box ``[left, top, width,
    height]`` (pixels), the seven features and their scaled values (null where undefined).

    Since ``percept.world/2``: ``visible``, whether it was seen in this frame (false for an
    object remembered out of view or behind a nearer one: its features are those of its last
    sighting, its box where that place falls in this frame's view), and ``last_seen``, the
    wall-clock time it was last seen (as ``stamp``; null in ``percept.world/1``)."""

    id: ObjectId
    bbox: tuple[float, float, float, float]
    features: Features
    scaled: Features = field(default_factory=dict)
    on_ground: bool = True
    age: Annotated[float, Range(0.0)] = 0.0
    in_motion: bool = False
    visible: bool = True
    last_seen: Stamp | None = None

    @property
    def position(self) -> tuple[float, float] | None:
        """``(x, y)`` on the ground, or None when the object has no ground position."""
        x, y = self.features.get("x"), self.features.get("y")
        if not self.on_ground or x is None or y is None:
            return None
        return x, y


#: Why a region is an agent: taller than ``[features] max_object_height`` (or standing in view
#: and reaching out of its top) or it came into view moving.
AGENT_REASONS = ("tall", "entered_moving")


@dataclass(frozen=True)
class WorldAgent:
    """An agent of a world model (since ``percept.world/2``, optional): a person or an arm, not
    an object. Its anchor ``id``, image box ``bbox`` ``[left, top, width, height]`` (pixels),
    ``x``, ``y`` and ``height`` on the ground (metres; null when its lower edge does not meet
    the ground, and the height only as far as it is in view), ``in_motion``, ``visible`` (seen
    in this frame) and ``reason``: ``tall`` (taller than ``[features] max_object_height``, or
    standing in view and reaching out of its top) or ``entered_moving`` (it came into view
    moving)."""

    id: ObjectId
    bbox: tuple[float, float, float, float]
    reason: Annotated[str, OneOf(AGENT_REASONS)]
    x: Position | None = None
    y: Position | None = None
    height: Position | None = None
    in_motion: bool = False
    visible: bool = True


_Row = Annotated[list[Annotated[float, Range(-1.01, 1.01)]], Size(3)]


class Camera(TypedDict):
    """The camera pose in the ground frame: ``R`` (3 rows of 3) turns the camera frame's
    vectors into the ground frame's, ``t`` is the camera centre (metres), ``frame`` the parent
    frame's name ("ground")."""

    R: Annotated[list[_Row], Size(3)]
    t: Annotated[list[Position], Size(3)]
    frame: NotRequired[Name]


@dataclass(frozen=True)
class World(_Json):
    """``percept.world/2``: one robot's world model after a frame: its camera pose, anchored
    objects (seen or remembered), boxes, the peers it has located and (optional, empty when
    left out) ``agents``: the regions that are people rather than objects
    (:class:`WorldAgent`), never among the objects. Beyond the contract:
    ``t``, the frame's monotonic time in the sender's process (null when unknown), and
    ``pose_fresh``, false when the joint readings behind the camera pose were too old.
    ``percept.world/1`` (objects without ``visible`` and ``last_seen``) is still read, as
    objects seen in the frame."""

    SCHEMA: ClassVar[str] = "percept.world/2"
    #: The keys' order in JSON (the fields' order is the constructor's).
    KEYS: ClassVar[tuple[str, ...]] = (
        "robot", "stamp", "t", "frame", "camera", "pose_fresh", "objects", "boxes", "peers",
        "agents",
    )  # fmt: skip
    robot: Name
    stamp: Stamp
    frame: int
    camera: Camera
    objects: Annotated[tuple[WorldObject, ...], Most(MAX_OBJECTS)]
    boxes: BoxList = ()
    peers: Annotated[dict[Name, PeerPose], Most(MAX_BOXES, "peers")] = field(default_factory=dict)
    t: float | None = None
    pose_fresh: bool = True
    agents: Annotated[tuple[WorldAgent, ...], Most(MAX_OBJECTS, "agents")] = ()


@dataclass(frozen=True)
class Status(_Json):
    """``percept.status/1``: how a robot's daemon is doing, about once a second. ``camera``,
        ``servos`` and ``peers`` are free-form JSON (their size is bounded by the payload's).

        Beyond the contract, what ``percept run`` also reports: the median milliseconds per frame,
        frames processed, frames with too old or no joint readings, the background model's state,
        the fraction of the last frame's view whose background is not known yet (a moving head
        looking where the calibration did not: ``background_unknown``, null before the first frame),
        peer messages dropped by a full inbox, the pointing games (``played``, ``success``,
        ``as_speaker``, ``ignored``: messages about games with robots that are not players) and the
        guessing games (the same counts prefixed ``guessing_``, and the robot's agent:
        ``lexicon_size`` word forms and ``categories``), CPU use (cores) in all and by thread
        (``cpu_threads``: cores by thread name, ``other`` the threads Python does not run; empty
        where the system does not tell), resident memory (MB), the recording's state (free-form,
        null when not recording) and ``unsent_messages``: the daemon's own messages that failed its
        own check and were not sent (a bug, reported in ``faults`` too), and how often a marker id
        was seen more than once in an image where its sightings did not agree on one box
        (``ambiguous_markers``; none of them used), the gaze (free-form: ``enabled``, ``state``,
        ``target``...) and the light as the background sees it (free-form: ``gain``, ``offset``,
        ``steady``, ``changed``, ``last_change``, ``changes``, ``relearned``, ``ghosts``; null when
        light adaptation is off), and the network (free-form: ``mode``, ``trust``, who can speak as
    a player, and ``games_look``, whether games from the network may turn the head)."""

    SCHEMA: ClassVar[str] = "percept.status/1"
    KEYS: ClassVar[tuple[str, ...]] = (
        "robot", "stamp", "fps", "ms_per_frame", "frames", "dropped_frames", "old_joint_frames",
        "frames_without_joints", "camera", "servos", "background", "background_unknown", "peers",
        "rejected_messages", "inbox_dropped", "games", "cpu", "cpu_threads", "rss_mb", "recording",
        "unsent_messages", "ambiguous_markers", "gaze", "light", "network", "faults",
    )  # fmt: skip
    robot: Name
    stamp: Stamp
    fps: Annotated[float, Range(0.0, 1e6)]
    dropped_frames: int
    camera: FreeJSON
    servos: FreeJSON
    peers: FreeJSON
    rejected_messages: int
    faults: Annotated[tuple[Annotated[str, Text(most=1024)], ...], Most(MAX_FAULTS)]
    ms_per_frame: Annotated[float, Range(0.0)] | None = None
    frames: int = 0
    old_joint_frames: int = 0
    frames_without_joints: int = 0
    background: Annotated[str, Text(most=MAX_TEXT)] = ""
    background_unknown: Annotated[float, Range(0.0, 1.0)] | None = None
    inbox_dropped: int = 0
    games: Counts = field(default_factory=dict)
    cpu: Annotated[float, Range(0.0, 1024.0)] | None = None
    cpu_threads: Shares = field(default_factory=dict)
    rss_mb: Annotated[float, Range(0.0)] | None = None
    recording: FreeJSON = None
    unsent_messages: int = 0
    ambiguous_markers: int = 0
    gaze: FreeJSON = None
    light: FreeJSON = None
    network: FreeJSON = None


@dataclass(frozen=True)
class PointingRequest(_Json):
    """``percept.pointing/1`` from the speaker: the topic is at ``(x, y)`` in its frame."""

    SCHEMA: ClassVar[str] = "percept.pointing/1"
    game: GameId
    sender: Annotated[Name, Key("from")]
    to: Name
    x: Position
    y: Position


@dataclass(frozen=True)
class _Choice(_Json):
    """A hearer's choice in game ``game``: an anchor (``object``, null for none) at ``(x, y)``
    in the hearer's frame (both or neither)."""

    game: GameId
    sender: Annotated[Name, Key("from")]
    to: Name
    object: ObjectId | None
    x: Annotated[Position | None, OMIT_NONE] = None
    y: Annotated[Position | None, OMIT_NONE] = None


@dataclass(frozen=True)
class PointingAnswer(_Choice):
    """``percept.pointing/1`` from the hearer: the anchor it chose (``object``, null for none)
    and, beyond the contract, that object's ``(x, y)`` in the hearer's frame, so the speaker can
    tell whether it is the same physical object."""

    SCHEMA: ClassVar[str] = "percept.pointing/1"


def _pointing(d: Mapping[str, JSON], where: str) -> PointingRequest | PointingAnswer:
    if "object" not in d:
        return PointingRequest.from_json(d, where)
    return _whole(PointingAnswer.from_json(d, where))


_Pointed = TypeVar("_Pointed", "PointingAnswer", "Guess", "Feedback")


def _whole(message: _Pointed) -> _Pointed:
    """``message`` with its optional position whole or none: half a position is none."""
    if message.x is None or message.y is None:
        return replace(message, x=None, y=None)
    return message


@dataclass(frozen=True)
class Signal(_Json):
    """``percept.signal/1``: agree, disagree, success or failure in game ``game``; and, from
    the joint-attention monitor, ``start``, naming who speaks and who hears and, beyond the
    contract, the game to ``play`` (null: pointing) and the ``objects`` of the context the two
    robots share: the addressee's anchor ids (null: its whole world model)."""

    SCHEMA: ClassVar[str] = "percept.signal/1"
    game: GameId
    sender: Annotated[Name, Key("from")]
    to: Name
    signal: Annotated[str, OneOf(SIGNALS)]
    speaker: Annotated[Name | None, OMIT_NONE] = None
    hearer: Annotated[Name | None, OMIT_NONE] = None
    play: Annotated[Game | None, OMIT_NONE] = None
    objects: Annotated[ObjectIds | None, OMIT_NONE] = None


@dataclass(frozen=True)
class Utterance(_Json):
    """``percept.utterance/1`` from a guessing game's speaker: the ``word`` it says for the
    topic."""

    SCHEMA: ClassVar[str] = "percept.utterance/1"
    game: GameId
    sender: Annotated[Name, Key("from")]
    to: Name
    word: Word


@dataclass(frozen=True)
class Guess(_Choice):
    """``percept.guess/1`` from a guessing game's hearer: it points at the object it takes the
    word to mean, its anchor id (``object``, null for none) at ``(x, y)`` in the hearer's
    frame."""

    SCHEMA: ClassVar[str] = "percept.guess/1"


@dataclass(frozen=True)
class Feedback(_Json):
    """``percept.feedback/1`` from a guessing game's speaker: ``success`` or ``failure``; on
    failure it points at the topic, ``(x, y)`` in the speaker's frame."""

    SCHEMA: ClassVar[str] = "percept.feedback/1"
    game: GameId
    sender: Annotated[Name, Key("from")]
    to: Name
    signal: Annotated[str, OneOf(OUTCOMES)]
    x: Annotated[Position | None, OMIT_NONE] = None
    y: Annotated[Position | None, OMIT_NONE] = None


Message = (
    Boxes
    | World
    | Status
    | PointingRequest
    | PointingAnswer
    | Signal
    | Utterance
    | Guess
    | Feedback
)

_READERS: dict[str, Callable[[Mapping[str, JSON], str], Message]] = {
    Boxes.SCHEMA: Boxes.from_json,
    World.SCHEMA: World.from_json,
    "percept.world/1": World.from_json,
    Status.SCHEMA: Status.from_json,
    PointingRequest.SCHEMA: _pointing,
    Signal.SCHEMA: Signal.from_json,
    Utterance.SCHEMA: Utterance.from_json,
    Guess.SCHEMA: lambda d, where: _whole(Guess.from_json(d, where)),
    Feedback.SCHEMA: lambda d, where: _whole(Feedback.from_json(d, where)),
}
SCHEMAS = tuple(_READERS)
#: Older versions still read, and the schema each is read as (on a key that carries that one).
OLDER = {"percept.world/1": World.SCHEMA}
#: The schema each key ``<prefix>/<robot>/<topic>`` carries.
TOPICS = {
    "world": World.SCHEMA,
    "boxes": Boxes.SCHEMA,
    "status": Status.SCHEMA,
    "pointing": PointingRequest.SCHEMA,
    "signal": Signal.SCHEMA,
    "utterance": Utterance.SCHEMA,
    "guess": Guess.SCHEMA,
    "feedback": Feedback.SCHEMA,
}


def document(message: Message) -> dict[str, JSON]:
    """The message as the JSON object it is sent and recorded as, ``schema`` first."""
    return {"schema": message.SCHEMA, **message.to_json()}


def encode(message: Message) -> bytes:
    """The message as a compact UTF-8 JSON payload naming its schema."""
    body = document(message)
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


def _no_constants(name: str) -> float:
    raise MessageError(f"{name} is not a number JSON allows")


def decode(payload: bytes | bytearray | memoryview | str, expect: str | None = None) -> Message:
    """The message in ``payload``; ``expect`` is the schema the key carries (None: any).

    Raises :class:`MessageError` for anything that is not a valid message of that schema:
    oversized, not UTF-8, not JSON, not an object, an unknown or unexpected schema, a missing
    field, a wrong type or a number out of range. An older version of the expected schema
    (:data:`OLDER`) is read as the current one.
    """
    try:
        raw = payload.encode() if isinstance(payload, str) else bytes(payload)
        if len(raw) > MAX_PAYLOAD:
            raise MessageError(f"payload of {len(raw)} bytes, more than {MAX_PAYLOAD}")
        data = json.loads(raw.decode("utf-8"), parse_constant=_no_constants)
        if not isinstance(data, dict):
            raise fail("payload", f"expected an object, got {show(data)}")
        schema = data.get("schema")
        if not isinstance(schema, str) or schema not in _READERS:
            raise fail("payload", f"unknown schema {show(schema)}")
        if expect is not None and OLDER.get(schema, schema) != expect:
            raise fail("payload", f"expected schema {expect}, got {schema}")
        return _READERS[schema](data, schema)
    except MessageError:
        raise
    except (ValueError, TypeError, RecursionError, OverflowError) as err:
        # Not UTF-8, not JSON, nested too deep, an integer too long to read: all just garbage.
        raise MessageError(f"not a JSON message: {type(err).__name__}: {err}") from None
