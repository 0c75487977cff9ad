"""Records of the scene data set (SPEC §4.11): one joint-attention scene per JSON line.

A scene holds, for each of the two robots, what its own pipeline made of the scene (its anchors
with raw and scaled features, and its estimate of where the other robot stands) and, for scoring
only, the truth as that robot should have perceived it: which true object each anchor is, and the
true features of every true object in the robot's own frame. Games read these records and never
anything else, so a data set recorded once is played many times.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from percept.runtime.net.codec import JSON

Features = dict[str, float | None]
Pose2 = tuple[float, float, float]  # x, y, theta in a robot's ground frame


def to_mine(peer: Pose2, x: float, y: float) -> tuple[float, float]:
    """A point ``(x, y)`` of the peer's frame in mine, ``peer`` being where it stands in mine:
    ``R(theta) (x, y) + (x_r, y_r)`` (as :func:`percept.runtime.net.peers.to_my_frame`, which
    the games do not import: it comes with Zenoh)."""
    x_r, y_r, theta = peer
    c, s = math.cos(theta), math.sin(theta)
    return x_r + c * x - s * y, y_r + s * x + c * y


@dataclass(frozen=True)
class SceneObject:
    """One anchor of a robot's world model: its id, raw and scaled features, whether a percept
    was associated with it in the scene's last frame, and (truth) the id of the true object it
    is, or None when it matches none."""

    id: str
    features: Features
    scaled: Features
    visible: bool
    truth: int | None

    def to_json(self) -> dict[str, JSON]:
        return {
            "id": self.id,
            "features": dict(self.features),
            "scaled": dict(self.scaled),
            "visible": self.visible,
            "truth": self.truth,
        }

    @classmethod
    def from_json(cls, d: Mapping[str, JSON]) -> SceneObject:
        return cls(
            id=str(d["id"]),
            features=_features(d["features"]),
            scaled=_features(d["scaled"]),
            visible=bool(d["visible"]),
            truth=None if d["truth"] is None else _int(d["truth"]),
        )


@dataclass(frozen=True)
class TrueObject:
    """A true object as one robot should perceive it: catalogue ``label``, true features in the
    robot's frame (position of the footprint's centre, width across the line of sight, height,
    colour of its visible pixels; None when it shows no pixel), their scaled values and the
    ``visible`` fraction of its outline in the robot's image."""

    id: int
    label: str
    features: Features
    scaled: Features
    visible: float

    def to_json(self) -> dict[str, JSON]:
        return {
            "id": self.id,
            "label": self.label,
            "features": dict(self.features),
            "scaled": dict(self.scaled),
            "visible": self.visible,
        }

    @classmethod
    def from_json(cls, d: Mapping[str, JSON]) -> TrueObject:
        return cls(
            id=_int(d["id"]),
            label=str(d["label"]),
            features=_features(d["features"]),
            scaled=_features(d["scaled"]),
            visible=_float(d["visible"]),
        )


@dataclass(frozen=True)
class RobotView:
    """One robot in one scene: its anchors, its estimate of the other robot's pose (None when it
    has none), and the truth: the other robot's true pose and the true objects, in its frame."""

    robot: str
    objects: tuple[SceneObject, ...]
    peer: Pose2 | None
    true_peer: Pose2
    truth: tuple[TrueObject, ...]

    def to_json(self) -> dict[str, JSON]:
        return {
            "robot": self.robot,
            "objects": [o.to_json() for o in self.objects],
            "peer": None if self.peer is None else list(self.peer),
            "true_peer": list(self.true_peer),
            "truth": [o.to_json() for o in self.truth],
        }

    @classmethod
    def from_json(cls, d: Mapping[str, JSON]) -> RobotView:
        return cls(
            robot=str(d["robot"]),
            objects=tuple(SceneObject.from_json(_object(o)) for o in _list(d["objects"])),
            peer=None if d["peer"] is None else _pose(d["peer"]),
            true_peer=_pose(d["true_peer"]),
            truth=tuple(TrueObject.from_json(_object(o)) for o in _list(d["truth"])),
        )


@dataclass(frozen=True)
class SceneRecord:
    """One joint-attention scene: its number, the seed it was made from, the two robots."""

    index: int
    seed: int
    robots: tuple[RobotView, RobotView]

    def to_json(self) -> dict[str, JSON]:
        return {
            "index": self.index,
            "seed": self.seed,
            "robots": [r.to_json() for r in self.robots],
        }

    @classmethod
    def from_json(cls, d: Mapping[str, JSON]) -> SceneRecord:
        first, second = (RobotView.from_json(_object(r)) for r in _list(d["robots"]))
        return cls(index=_int(d["index"]), seed=_int(d["seed"]), robots=(first, second))


class SceneFileError(ValueError):
    """A scenes file that cannot be read; names the file and the line."""


def write_scenes(path: str | Path, scenes: Iterable[SceneRecord]) -> int:
    """Write scenes as JSON lines; returns how many."""
    n = 0
    with Path(path).open("w", encoding="utf-8") as fh:
        for scene in scenes:
            fh.write(dumps(scene) + "\n")
            n += 1
    return n


def dumps(scene: SceneRecord) -> str:
    """One scene as its JSON line (without the newline)."""
    return json.dumps(scene.to_json(), separators=(",", ":"))


def read_scenes(path: str | Path) -> Iterator[SceneRecord]:
    """The scenes of a JSON-lines file, in order; blank lines skipped. Raises
    :class:`SceneFileError` naming the line of a malformed record."""
    path = Path(path)
    with path.open(encoding="utf-8") as fh:
        for number, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                yield SceneRecord.from_json(json.loads(line))
            except (ValueError, KeyError, TypeError) as err:
                raise SceneFileError(f"{path}:{number}: not a scene record ({err!r})") from None


# Parsed JSON read as int() and float() would read it, and refused (TypeError) where they would
# fail: what read_scenes reports as a malformed record.


def _int(v: JSON) -> int:
    if isinstance(v, str | int | float):
        return int(v)
    raise TypeError(f"expected a number, got {type(v).__name__}")


def _float(v: JSON) -> float:
    if isinstance(v, str | int | float):
        return float(v)
    raise TypeError(f"expected a number, got {type(v).__name__}")


def _list(v: JSON) -> list[JSON]:
    if isinstance(v, list):
        return v
    raise TypeError(f"expected a list, got {type(v).__name__}")


def _object(v: JSON) -> dict[str, JSON]:
    if isinstance(v, dict):
        return v
    raise TypeError(f"expected an object, got {type(v).__name__}")


def _features(v: JSON) -> Features:
    return {str(k): None if x is None else _float(x) for k, x in _object(v).items()}


def _pose(v: JSON) -> Pose2:
    x, y, theta = (_float(c) for c in _list(v))
    return x, y, theta
