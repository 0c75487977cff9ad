"""Where the head must turn to look at a point: inverse kinematics of the head chain.

The same :class:`~percept.kinematics.tree.KinematicTree` that gives the camera pose (forward
kinematics) is inverted numerically: the gaze joints are solved, within their limits, so that
the camera's optical axis (x of the camera frame) passes through the target. The error is
measured as the two angles under which the camera sees the target off its axis (azimuth and
elevation), which are zero exactly when the axis goes through it; bounded least squares
(:mod:`~percept.kinematics.least_squares`) keeps every joint inside its range, so a target the
head cannot face is found out by the error left over, and refused with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from percept.kinematics.least_squares import levenberg_marquardt, row_by_row
from percept.kinematics.tree import KinematicTree

Vec3 = tuple[float, float, float]

LOOK_TOLERANCE = math.radians(0.01)
"""The optical axis passes this close to a target that :func:`look_at` accepts."""


class Unreachable(ValueError):
    """A target the head cannot look at; the message says why."""


@dataclass(frozen=True)
class Limits:
    """The range of one gaze joint, radians."""

    min: float
    max: float


def _in_camera(tree: KinematicTree, angles: Mapping[str, float], target: np.ndarray) -> np.ndarray:
    """``target`` (ground frame) in the camera frame of joint ``angles``."""
    pose = tree.camera_pose(angles)
    return pose.R.T @ (target - pose.t)


def off_axis(tree: KinematicTree, angles: Mapping[str, float], target: Vec3) -> float:
    """The angle between the camera's optical axis and the direction to ``target`` (radians),
    for joint ``angles``; targets are in the robot's ground frame."""
    d = _in_camera(tree, angles, np.asarray(target, dtype=float))
    norm = float(np.linalg.norm(d))
    if norm == 0.0:
        return math.pi
    return math.acos(max(-1.0, min(1.0, float(d[0]) / norm)))


def _seen_at(tree: KinematicTree, angles: Mapping[str, float], target: np.ndarray) -> np.ndarray:
    """(azimuth, elevation) of ``target`` in the camera frame: 0, 0 on the optical axis."""
    d = _in_camera(tree, angles, target)
    return np.array([math.atan2(d[1], d[0]), math.atan2(d[2], math.hypot(d[0], d[1]))])


def look_at(
    tree: KinematicTree,
    target: Vec3,
    limits: Mapping[str, Limits],
    start: Mapping[str, float] | None = None,
) -> dict[str, float]:
    """Angles of the gaze joints (the keys of ``limits``) that put ``target`` (ground frame,
    metres) on the optical axis, each within its limits; the other joints of the tree stay at
    their ``start`` angles (0 if not given). Raises :class:`Unreachable` with the reason."""
    names = list(limits)
    if not names:
        raise ValueError("no gaze joints")
    point = np.asarray(target, dtype=float)
    if point.shape != (3,) or not np.isfinite(point).all():
        raise Unreachable(f"target {target} is not a point")
    base = dict(start or {})
    lo = np.array([limits[n].min for n in names])
    hi = np.array([limits[n].max for n in names])

    def angles(q: np.ndarray) -> dict[str, float]:
        return {**base, **{n: float(v) for n, v in zip(names, q, strict=True)}}

    def residual(q: np.ndarray) -> np.ndarray:
        return _seen_at(tree, angles(q), point)

    best: tuple[float, np.ndarray] | None = None
    for guess in _guesses(base, names, lo, hi):
        q, _ = levenberg_marquardt(row_by_row(residual), guess, tolerance=1e-12, lower=lo, upper=hi)
        error = off_axis(tree, angles(q), target)
        if best is None or error < best[0]:
            best = (error, q)
        if error <= LOOK_TOLERANCE:
            break
    assert best is not None
    error, q = best
    if error > LOOK_TOLERANCE:
        raise Unreachable(_why(names, q, lo, hi, error, target))
    return angles(q)


def _guesses(
    base: Mapping[str, float], names: Sequence[str], lo: np.ndarray, hi: np.ndarray
) -> list[np.ndarray]:
    """Starting points: where the joints are, the middle of their ranges, then the quarter
    points (a chain with offsets can have a second, worse local minimum behind the first)."""
    middle = (lo + hi) / 2.0
    here = np.array([base.get(n, m) for n, m in zip(names, middle, strict=True)])
    starts = [here, middle, lo + 0.25 * (hi - lo), lo + 0.75 * (hi - lo)]
    return [np.clip(s, lo, hi) for s in starts]


def _why(
    names: Sequence[str],
    q: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    error: float,
    target: Vec3,
) -> str:
    stuck = []
    for name, value, low, high in zip(names, q, lo, hi, strict=True):
        if value <= low + 1e-6:
            stuck.append(f"{name} at its lower limit {low:+.3f}")
        elif value >= high - 1e-6:
            stuck.append(f"{name} at its upper limit {high:+.3f}")
    where = ", ".join(f"{c:.3f}" for c in target)
    return (
        f"target ({where}) is outside the head's range: "
        + (", ".join(stuck) if stuck else "no joint angles face it")
        + f", the optical axis still {math.degrees(error):.1f} deg off"
    )


def sweep_grid(
    limits: Mapping[str, Limits],
    pan: tuple[float, float] | None = None,
    tilt: tuple[float, float] | None = None,
    steps: tuple[int, int] = (5, 3),
) -> list[dict[str, float]]:
    """A grid of head poses over the working range (default: each joint's whole range), row by
    row, back and forth so the head never jumps across it. The first joint of ``limits`` pans,
    the second tilts; a range beyond a joint's limits is cut to them."""
    names = list(limits)
    ranges = [pan, tilt]
    axes: list[np.ndarray] = []
    for k, name in enumerate(names[:2]):
        lim = limits[name]
        lo, hi = ranges[k] or (lim.min, lim.max)
        lo, hi = max(lo, lim.min), min(hi, lim.max)
        axes.append(np.linspace(lo, hi, max(1, steps[k])))
    if len(axes) == 1:
        return [{names[0]: float(a)} for a in axes[0]]
    out: list[dict[str, float]] = []
    for row, b in enumerate(axes[1]):
        across = axes[0] if row % 2 == 0 else axes[0][::-1]
        out.extend({names[0]: float(a), names[1]: float(b)} for a in across)
    return out


def sweep_keyframes(
    poses: Sequence[Mapping[str, float]], speed: float, dwell: float
) -> dict[str, list[tuple[float, float]]]:
    """``[[t, angle], ...]`` per joint of a head that goes through ``poses`` in order, the
    slowest joint of each move at ``speed`` (rad/s), resting ``dwell`` seconds at each pose."""
    if speed <= 0 or dwell < 0:
        raise ValueError("speed must be positive and dwell not negative")
    names = list(poses[0]) if poses else []
    frames: dict[str, list[tuple[float, float]]] = {n: [] for n in names}
    t = 0.0
    here = dict(poses[0]) if poses else {}
    for pose in poses:
        t += max(abs(pose[n] - here[n]) for n in names) / speed
        for n in names:
            if frames[n] and frames[n][-1][0] >= t:
                continue
            frames[n].append((t, pose[n]))
        t += dwell
        for n in names:
            frames[n].append((t, pose[n]))
        here = dict(pose)
    return frames
