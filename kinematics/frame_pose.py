"""The camera pose at a frame's time, from joint readings matched to that time.

A camera frame taken at monotonic time ``t`` is paired with the joint angles interpolated to ``t``
(a servo source's ``angles_at(t)``). When the readings behind those angles are older than a bound,
or a joint on the camera's chain has stopped answering, the pose is still computed (from the last
known angles) but marked not ``fresh``, so that features from it can be flagged or dropped.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from percept.kinematics.pose import CameraPose
from percept.kinematics.tree import KinematicTree


class AngleSample(Protocol):
    """Joint angles at a time, with the age of the readings behind them (e.g.
    ``percept.drivers.joints.JointSample``)."""

    @property
    def angles(self) -> Mapping[str, float]: ...

    @property
    def t(self) -> float: ...

    @property
    def age(self) -> float: ...

    @property
    def stale(self) -> frozenset[str]: ...


@dataclass(frozen=True)
class FramePose:
    """The camera pose for the frame at time ``t``; ``fresh`` is False when the joint readings
    are older than the bound or a joint of the camera chain is stale or missing."""

    pose: CameraPose
    t: float
    joint_age: float
    fresh: bool
    problems: tuple[str, ...] = ()


def pose_for_frame(
    tree: KinematicTree, sample: AngleSample, max_age: float, pose: CameraPose | None = None
) -> FramePose:
    """The camera pose from ``sample`` (angles at the frame's time), checked against ``max_age``;
    ``pose``: the camera pose at ``sample``'s angles when the caller has it (else computed)."""
    chain = tree.camera_joints
    problems: list[str] = []
    missing = [name for name in chain if name not in sample.angles]
    if missing:
        problems.append(f"no reading of {', '.join(missing)}")
    stale = sorted(set(chain) & set(sample.stale))
    if stale:
        problems.append(f"stale joint(s) {', '.join(stale)}")
    if sample.age > max_age:
        problems.append(f"joint readings {sample.age * 1000:.0f} ms old (max {max_age * 1000:.0f})")
    return FramePose(
        pose=tree.camera_pose(sample.angles) if pose is None else pose,
        t=sample.t,
        joint_age=sample.age,
        fresh=not problems,
        problems=tuple(problems),
    )


class FramePoses:
    """:func:`pose_for_frame` frame after frame, the forward kinematics done again only when the
    joint angles change: the frames of a still head share one :class:`CameraPose`, so that
    :func:`~percept.kinematics.pose.same_pose` answers at once and what was computed from that
    pose holds for them all."""

    def __init__(self, tree: KinematicTree, max_age: float) -> None:
        self.tree = tree
        self.max_age = max_age
        self._last: tuple[dict[str, float], CameraPose] | None = None

    def __call__(self, sample: AngleSample) -> FramePose:
        angles = dict(sample.angles)
        last = self._last
        if last is not None and last[0] == angles:
            pose = last[1]
        else:
            pose = self.tree.camera_pose(angles)
            self._last = (angles, pose)
        return pose_for_frame(self.tree, sample, self.max_age, pose)
