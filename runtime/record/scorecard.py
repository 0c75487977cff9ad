"""Scoring robots' world models against the simulated truth: the demo's table, summary and
figure (the chapter's Fig. 5.5), and the truth of the language games' scene data set
(:mod:`percept.runtime.games.language.dataset.joint_scenes`).

Everything here is a pure function of world models (:class:`~percept.runtime.net.messages.World`)
and truth records; the truth is given in the world frame of the scene and turned into each
robot's ground frame with the robot's true pose.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from percept.kinematics.pose import wrap
from percept.perception.assignment import linear_sum_assignment
from percept.perception.features.experience import FEATURES
from percept.runtime.net.messages import ObjectId, World, WorldObject

SHARED = ("width", "height", "luminance", "green_red", "yellow_blue")  # not egocentric
MATCH_GATE = 0.35  # metres: an anchor farther than this from every true object matches none


@dataclass(frozen=True)
class TruthObject:
    """A true object in the scene's world frame: id, label, footprint centre ``(x, y)``,
    ``size`` (x, y, height; metres) and RGB colour (0-255)."""

    id: int
    label: str
    x: float
    y: float
    size: tuple[float, float, float]
    rgb: tuple[int, int, int]


Pose2 = tuple[float, float, float]  # x, y, yaw in the world frame


def to_robot(pose: Pose2, x: float, y: float) -> tuple[float, float]:
    """A world-frame point in the ground frame of a robot standing at ``pose``."""
    px, py, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = x - px, y - py
    return c * dx + s * dy, -s * dx + c * dy


def relative_pose(me: Pose2, other: Pose2) -> Pose2:
    """Where ``other`` stands in the ground frame of ``me``: (x, y, theta)."""
    x, y = to_robot(me, other[0], other[1])
    return x, y, wrap(other[2] - me[2])


#: An anchor matched to a true object, and their distance on the ground (metres).
Match = tuple[WorldObject, TruthObject, float]


def placed(world: World) -> list[WorldObject]:
    """The anchors with a ground position: those that can be scored against the truth."""
    return [o for o in world.objects if o.position is not None]


def distances(
    objects: Sequence[WorldObject], truth: Sequence[TruthObject], pose: Pose2
) -> np.ndarray:
    """``(len(objects), len(truth))`` ground distances (metres) of placed anchors to true
    objects, in the robot's frame."""
    if not objects or not truth:
        return np.zeros((len(objects), len(truth)))
    true_xy = np.array([to_robot(pose, t.x, t.y) for t in truth])
    seen_xy = np.array([o.position for o in objects])
    return np.asarray(np.linalg.norm(seen_xy[:, None, :] - true_xy[None, :, :], axis=2))


def match(
    world: World, truth: Sequence[TruthObject], pose: Pose2, gate: float = MATCH_GATE
) -> list[Match]:
    """Anchors with a ground position matched one-to-one to true objects (Hungarian on ground
    distance in the robot's frame, pairs farther than ``gate`` dropped): (object, truth,
    distance) triples."""
    objects = placed(world)
    if not objects or not truth:
        return []
    cost = distances(objects, truth, pose)
    rows, cols = linear_sum_assignment(cost)
    return [
        (objects[r], truth[c], float(cost[r, c]))
        for r, c in zip(rows, cols, strict=True)
        if cost[r, c] <= gate
    ]


def peer_error(world: World, peer: str, truth: Pose2) -> tuple[float, float] | None:
    """(position error in metres, heading error in radians) of the peer's estimated pose, or
    None when the world model has no pose of it."""
    est = world.peers.get(peer)
    if est is None:
        return None
    return math.hypot(est.x - truth[0], est.y - truth[1]), abs(wrap(est.theta - truth[2]))


def scaled_differences(matches: Mapping[str, list[Match]]) -> dict[int, dict[str, float]]:
    """For each true object both robots matched: per feature the absolute difference of the two
    robots' scaled values (the last column of Fig. 5.5). ``matches`` by robot, two robots."""
    (_, first), (_, second) = sorted(matches.items())[:2]
    by_truth_b = {t.id: o for o, t, _ in second}
    out: dict[int, dict[str, float]] = {}
    for obj_a, truth, _ in first:
        obj_b = by_truth_b.get(truth.id)
        if obj_b is None:
            continue
        diffs = {}
        for name in FEATURES:
            a, b = obj_a.scaled.get(name), obj_b.scaled.get(name)
            if a is not None and b is not None:
                diffs[name] = abs(a - b)
        out[truth.id] = diffs
    return out


def mean(values: Iterable[float | None]) -> float | None:
    """The mean of the known, finite values, to 4 decimals (None: none is)."""
    known = _known(values)
    return round(statistics.fmean(known), 4) if known else None


def median(values: Iterable[float | None]) -> float | None:
    """The median of the known, finite values, to 4 decimals (None: none is)."""
    known = _known(values)
    return round(statistics.median(known), 4) if known else None


def _known(values: Iterable[float | None]) -> list[float]:
    return [v for v in values if v is not None and math.isfinite(v)]


ROUND = ("cylinder", "cone", "ball")


def true_width(shape: str, size: Sequence[float], turn: np.ndarray, across: np.ndarray) -> float:
    """The true width of an object: the extent of its footprint along ``across`` (the unit
    horizontal direction across the line of sight), where ``turn`` (2x2) turns the object's
    frame into the frame of ``across``."""
    if shape in ROUND:
        return float(size[0])
    if shape == "toy":  # its widest part is an ellipsoid body filling the footprint box
        a, b = turn.T @ across
        return float(np.hypot(a * size[0], b * size[1]))
    half = np.array([[a * size[0], b * size[1]] for a in (-0.5, 0.5) for b in (-0.5, 0.5)])
    return float(np.ptp((half @ turn.T) @ across))


LONG_FALSE = 10.0  # seconds: a false anchor matched to nothing longer than this is persistent


class Precision:
    """How a robot's world models track the true objects, one world model after another:
    CLEAR-MOT (MOTA) and IDF1 with an anchor and a true object matching when they are at most
    ``gate`` apart on the ground, and its false anchors (anchors with a ground position matched
    to no true object): how many per world model, and for how long each id was one."""

    def __init__(self, pose: Pose2, gate: float = MATCH_GATE) -> None:
        from percept.perception.evaluation.tracking import ClearMot

        self.pose, self.gate = pose, gate
        # Nearness 1 - distance / gate is at least 0 within the gate.
        self._mot = ClearMot(0.0)
        self.false_counts: list[int] = []
        self.false_seconds: dict[ObjectId, float] = {}
        self._last: tuple[float, set[ObjectId]] | None = None
        self._numbers: dict[ObjectId, int] = {}
        """A number for each anchor id (ids are text, ``o12``, or numbers), for the scoring."""

    def add(self, world: World, truth: Sequence[TruthObject]) -> set[ObjectId]:
        """Score one world model against the truth at its time; the ids of its false anchors."""
        objects = placed(world)
        near = 1.0 - distances(objects, truth, self.pose).T / self.gate
        g_ids = np.array([t.id for t in truth], int)
        numbers = self._numbers
        h_ids = np.array([numbers.setdefault(o.id, len(numbers)) for o in objects], int)
        matched = {c for _, c in self._mot.add(g_ids, h_ids, near)}
        false = {objects[c].id for c in range(len(objects)) if c not in matched}
        self.false_counts.append(len(false))
        if self._last is not None:
            since, before = self._last
            for i in false & before:
                self.false_seconds[i] = self.false_seconds.get(i, 0.0) + world.stamp - since
        self._last = (world.stamp, false)
        return false

    def scores(self) -> tuple[float | None, float | None]:
        """(MOTA, IDF1) over the world models added, to 4 decimals (None: undefined)."""
        s = self._mot.scores()
        return _rounded(s.mota), _rounded(s.idf1)

    def long_false(self, seconds: float = LONG_FALSE) -> int:
        """How many anchors were false for more than ``seconds`` in all."""
        from percept.perception.evaluation.false_anchors import persistent

        return persistent(self.false_seconds, seconds)


def _rounded(v: float) -> float | None:
    return round(v, 4) if math.isfinite(v) else None
