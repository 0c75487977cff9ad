"""How late the calibration's poses are: the lag of the joint angles behind the images, found by
aligning the calibration frames with the mosaic made of them.

Joint angles read a little before or after the image was taken (a delay in the encoders' bus, a
timestamp off by some milliseconds) put each frame of a sweep where the head was that much
earlier: off by the head's motion times the lag, one way while the sweep goes left and the other
way while it comes back. A mosaic made of such frames holds every edge twice, a few cells
apart, and a frame of a head that holds still later shows each edge where the mosaic has none:
foreground that no refinement of the frame's alignment removes, since the mosaic itself is
smeared.

So each calibration frame is aligned with the mosaic made of all of them (the phase correlation
of :class:`~percept.perception.view.follow.Correlator`), and the turns found are fitted as a
constant offset (pan, tilt; the mosaic's own, which the frames share and which stays) plus the
lag times the view's motion per frame; the mosaic is then made again of the poses turned by the
lag, and the lag found on that one is added, :data:`PASSES` times. A lag that the poses do not
show (a head that held still or moved evenly) is 0. The frames that follow take the same lag
(:class:`~percept.perception.view.follow.FollowingBackground`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, wrap
from percept.perception.view.follow import Correlator, aim_of, turn_of, turned
from percept.perception.view.map.directions import Lookup
from percept.perception.view.mosaic import ViewMosaic

PASSES = 3
"""Times the lag is found and the mosaic made again: each pass recovers most of what is left
(the first sees a smeared mosaic)."""
MIN_MOTION = 0.5
"""Grid pixels: below this spread of the view's motion per frame the lag is not observable."""
MosaicBuilder = Callable[[list[CameraPose]], ViewMosaic]
"""Makes the mosaic of the calibration frames taken at the poses given."""

OUTLIER = 3.0
"""Turns off the fit by more than this many (robust) deviations are dropped before refitting."""


def motions(poses: list[CameraPose]) -> np.ndarray:
    """(n, 2) the change of each pose's aim (azimuth, elevation; radians) since the previous
    pose (the first: that of the second)."""
    aims = np.array([aim_of(p) for p in poses])
    moved = np.zeros_like(aims)
    if len(aims) > 1:
        moved[1:] = np.diff(aims, axis=0)
        moved[0] = moved[1]
    moved[:, 0] = wrap(moved[:, 0])
    return moved


def lagged(poses: list[CameraPose], moved: np.ndarray, lag: float) -> list[CameraPose]:
    """``poses`` turned by ``lag`` times their motion per frame ``moved``."""
    if lag == 0.0:
        return poses
    return [
        turned(p, float(lag * m[0]), float(lag * m[1])) for p, m in zip(poses, moved, strict=True)
    ]


def frame_turns(
    mosaic: ViewMosaic,
    brightness: list[np.ndarray],
    poses: list[CameraPose],
    lookup: Lookup,
    K: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) pan and tilt (radians) by which each frame's grid ``brightness`` lies turned
    against ``mosaic`` seen from its pose, and (n,) whether it was found."""
    correlator = Correlator()
    turns = np.zeros((len(poses), 2))
    found = np.zeros(len(poses), bool)
    for k, (y, pose) in enumerate(zip(brightness, poses, strict=True)):
        cells = lookup(mosaic.directions, pose)
        shift = correlator.shift(mosaic.brightness_at(cells), y)
        if shift != (0.0, 0.0):
            turns[k] = turn_of(pose, shift, K)
            found[k] = True
    return turns, found


def fit_lag(turns: np.ndarray, moved: np.ndarray, found: np.ndarray, fx: float) -> float:
    """The lag (frames) that best explains ``turns`` (n, 2) as a constant offset plus the lag
    times the motion per frame ``moved`` (n, 2), over the frames ``found``; 0 when the motion
    does not vary by :data:`MIN_MOTION` grid pixels (``fx`` the grid's focal length)."""
    m, v = turns[found], moved[found]
    if len(m) < 3 or float(np.std(v, axis=0).max()) * fx < MIN_MOTION:
        return 0.0
    # Unknowns: offset pan, offset tilt, lag; two equations per frame.
    A = np.zeros((2 * len(m), 3))
    A[0::2, 0], A[1::2, 1] = 1.0, 1.0
    A[0::2, 2], A[1::2, 2] = v[:, 0], v[:, 1]
    b = m.reshape(-1)
    keep = np.ones(len(b), bool)
    for _ in range(2):
        solution = np.linalg.lstsq(A[keep], b[keep], rcond=None)[0]
        residual = np.abs(A @ solution - b)
        spread = 1.4826 * float(np.median(residual[keep]))
        keep = residual <= max(OUTLIER * spread, 0.5 / fx)
    return float(solution[2])


def pose_lag(
    build: MosaicBuilder,
    frames_y: list[np.ndarray],
    poses: list[CameraPose],
    camera: CameraModel,
    step: int,
    K: np.ndarray,
    max_turn: float,
) -> tuple[float, ViewMosaic]:
    """The lag of ``poses`` behind the frames (whose grid brightness is ``frames_y``), and the
    mosaic ``build`` makes of the poses turned by it. A lag that would turn a pose by more than
    ``max_turn`` radians is not believed (0)."""
    moved = motions(poses)
    lookup = Lookup(camera, step, frames_y[0].shape[:2])
    lag = 0.0
    mosaic = build(poses)
    for _ in range(PASSES):
        current = lagged(poses, moved, lag)
        turns, found = frame_turns(mosaic, frames_y, current, lookup, K)
        more = fit_lag(turns, moved, found, float(K[0, 0]))
        if more == 0.0:
            break
        if abs(lag + more) * float(np.abs(moved).max()) > max_turn:
            break
        lag += more
        mosaic = build(lagged(poses, moved, lag))
    return lag, mosaic
