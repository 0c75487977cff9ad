"""Inverse kinematics of the head chain against forward kinematics of the same tree."""

from __future__ import annotations

import math

import numpy as np
import pytest

from percept.kinematics.gaze import Limits, Unreachable, look_at, off_axis
from percept.kinematics.tree import KinematicTree
from percept.runtime.settings.profile import load_profile

PROFILES = ["robotis-op3", "myon", "sony-humanoid"]


def head(profile: str) -> tuple[KinematicTree, dict[str, Limits]]:
    p = load_profile(profile)
    tree = KinematicTree.from_settings(p.kinematics)
    return tree, {j.name: Limits(j.min, j.max) for j in p.joints}


@pytest.mark.parametrize("profile", PROFILES)
def test_ik_round_trip_against_fk_within_a_tenth_of_a_degree(profile: str) -> None:
    """Joint angles anywhere in range -> FK -> a point on the optical axis -> IK -> the same
    joint angles and an optical axis through the point."""
    tree, limits = head(profile)
    rng = np.random.default_rng(17)
    for _ in range(40):
        q = {n: rng.uniform(lim.min, lim.max) for n, lim in limits.items()}
        pose = tree.camera_pose(q)
        target = tuple(pose.t + rng.uniform(0.3, 3.0) * pose.R[:, 0])
        got = look_at(tree, target, limits)  # type: ignore[arg-type]
        for name in q:
            assert abs(math.degrees(got[name] - q[name])) < 0.1, (name, q, got)
        assert math.degrees(off_axis(tree, got, target)) < 0.1  # type: ignore[arg-type]


@pytest.mark.parametrize("profile", PROFILES)
def test_floor_points_around_the_robot(profile: str) -> None:
    """Objects on the floor spread +-60 deg in front of the robot are looked at exactly."""
    tree, limits = head(profile)
    for bearing in np.radians([-60, -30, 0, 30, 60]):
        for distance in (1.0, 1.5, 2.5):  # nearer, the tall myon cannot look down enough
            target = (distance * math.cos(bearing), distance * math.sin(bearing), 0.0)
            got = look_at(tree, target, limits)
            assert off_axis(tree, got, target) < math.radians(0.01)
            assert all(limits[n].min <= got[n] <= limits[n].max for n in limits)


def test_a_target_outside_the_range_is_refused_with_the_reason() -> None:
    tree, limits = head("robotis-op3")
    with pytest.raises(Unreachable, match=r"outside the head's range: head_pan at its upper"):
        look_at(tree, (-1.0, 0.2, 0.0), limits)  # behind the robot
    # Straight up: beyond the tilt range (head_tilt 0.6 at most).
    with pytest.raises(Unreachable, match="head_tilt at its"):
        look_at(tree, (0.05, 0.0, 3.0), limits)
    with pytest.raises(Unreachable, match="not a point"):
        look_at(tree, (math.nan, 0.0, 0.0), limits)
