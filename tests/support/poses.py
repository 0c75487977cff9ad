"""Robots' poses on the ground for the game tests: what a robot sees of a point, and where it
sees the other robot."""

from __future__ import annotations

import math

from percept.runtime.net.messages import PeerPose

Pose = tuple[float, float, float]  # x, y (metres) and heading (radians) in the world


def seen_from(robot: Pose, x: float, y: float) -> tuple[float, float]:
    """The world point ``(x, y)`` in the robot's ground frame."""
    rx, ry, rt = robot
    c, s = math.cos(rt), math.sin(rt)
    return c * (x - rx) + s * (y - ry), -s * (x - rx) + c * (y - ry)


def relative(a: Pose, b: Pose) -> PeerPose:
    """Robot b's pose in robot a's frame."""
    x, y = seen_from(a, b[0], b[1])
    return PeerPose(x, y, math.remainder(b[2] - a[2], math.tau), 0.0, 1)
