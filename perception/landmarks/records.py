"""The box pose record and its arithmetic (no OpenCV: messages and peers use it too)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from percept.kinematics.pose import wrap
from percept.perception.landmarks.geometry import circular_mean


@dataclass(frozen=True)
class BoxPose:
    """A box on the ground in a robot's ground frame: ``x``, ``y`` (metres) of its footprint's
    centre, ``theta`` (radians) the heading of its front, and ``n`` the marker sightings behind
    the estimate."""

    id: int
    x: float
    y: float
    theta: float
    n: int = 1

    def as_dict(self) -> dict[str, float | int]:
        """``{id, x, y, theta, n}`` as in the ``percept.boxes/1`` message."""
        return {"id": self.id, "x": self.x, "y": self.y, "theta": self.theta, "n": self.n}


def average(poses: list[BoxPose]) -> BoxPose:
    """The mean of poses of one box: positions arithmetically, headings by circular mean, each
    weighted by its sightings; ``n`` is their sum."""
    w = np.array([p.n for p in poses], dtype=float)
    x = float(np.average([p.x for p in poses], weights=w))
    y = float(np.average([p.y for p in poses], weights=w))
    theta = circular_mean([p.theta for p in poses], w)
    return BoxPose(poses[0].id, x, y, theta, int(w.sum()))


def box_error(estimate: BoxPose, x: float, y: float, theta: float) -> tuple[float, float]:
    """Position (metres) and heading (radians) error of ``estimate`` against the truth."""
    return math.hypot(estimate.x - x, estimate.y - y), abs(wrap(estimate.theta - theta))
