"""The background while the head moves (issue 16, items 1-2): false foreground and motion on the
empty floor during head turns, the residual alignment error, and ms/frame with a still and a
moving head.

Robot a of ``tabletop-busy`` with the floor emptied (no objects) sweeps its head over pan
-0.45..0.45 rad in the first 2 s (the calibration: 30 frames with their camera poses), then turns
to 0, -0.3, 0.3 and 0 again between 2 and 10 s (keyframes below) while frames are taken at
15 fps. Every number is against the simulation's truth: the floor is empty, so every foreground
or motion pixel is false; the pose from forward kinematics is exact, so the residual alignment
error is how far (grid pixels) the refined lookup of each pixel lies from the lookup at the true
pose, when the pose given is 1 degree off in pan, tilt or both, or 20 ms late.

Rows (``--size``, default the profile's 320x200):

- ``percept``: the background over viewing directions, refined, with motion compensation;
- ``no refinement``: the same, trusting the pose (``view.refine = false``);
- ``no compensation``: motion between the frames as they are (``view.compensate = false``);
- ``still model``: today's per-pixel model, calibrated with the head still at pan 0 (what
  percept did before).

Speed: ms/frame (median, p90; one thread; rendering not timed) of ``Perception.process`` at
176x144 and 640x480 on ``tabletop-busy`` with its objects (frames from 2 s on), the head still at
pan 0 (calibrated there, without and with poses) or sweeping for the calibration and turning as
above (then only the frames in which the head turns count).

    python bench/bench_following.py [--size 320x200] [--speed-sizes 176x144 640x480] [--json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from percept.perception.params import PerceptionParams, ViewParams  # noqa: E402
from percept.perception.pipeline import Perception  # noqa: E402
from percept.perception.segmentation.labelling.regions import subsample  # noqa: E402
from tests.support.moving_head import PanningRobot  # noqa: E402

FPS = 15.0
CALIBRATION = (0.0, 2.0)
PAN = ((0.0, -0.45), (2.0, 0.45), (3.0, 0.0), (4.5, 0.0), (5.5, -0.3), (7.0, -0.3), (8.5, 0.3),
       (9.5, 0.0), (10.0, 0.0))  # fmt: skip
RUN = (2.0, 10.0)
ERRORS = {  # pan and tilt error (degrees), delay (seconds)
    "exact pose": (0.0, 0.0, 0.0),
    "pan 1 deg off": (1.0, 0.0, 0.0),
    "tilt 1 deg off": (0.0, 1.0, 0.0),
    "pan and tilt 1 deg": (1.0, 1.0, 0.0),
    "20 ms late": (0.0, 0.0, 0.02),
}


def calibrated(robot: PanningRobot, params: PerceptionParams, still: bool = False) -> Perception:
    p = Perception(params, robot.camera.width, robot.camera.height, robot.camera)
    times = np.linspace(*CALIBRATION, params.background.calibration_frames)
    if still:  # the head held at pan 0 (as the shipped scenes do), the same frame each time
        robot.calibrated(p, np.full(len(times), 4.0), poses=False)
    else:
        robot.calibrated(p, times)
    return p


def floor(robot: PanningRobot) -> dict[str, dict[str, float]]:
    """False foreground and motion on the empty floor while the head turns."""
    times = np.arange(RUN[0], RUN[1], 1 / FPS)
    frames = robot.frames(times)
    rows = {
        "percept": (PerceptionParams(), False),
        "no refinement": (_view(refine=False), False),
        "no compensation": (_view(compensate=False), False),
        "still model": (PerceptionParams(), True),
    }
    out = {}
    for name, (params, still) in rows.items():
        p = calibrated(robot, params, still)
        fg, moved, unknown = [], [], []
        for t, frame in zip(times, frames, strict=True):
            r = p.process(frame, float(t), None if still else robot.pose(float(t)))
            assert r.masks is not None
            fg.append(float(r.masks.fg.mean()))
            moved.append(float(r.masks.moved.mask().mean()))
            unknown.append(r.unknown_fraction)
        turning = [abs(pan_rate(t)) > 0 for t in times]
        out[name] = {
            "foreground_mean": float(np.mean(fg)),
            "foreground_max": float(np.max(fg)),
            "foreground_turning": float(np.mean(np.array(fg)[turning])),
            "motion_turning": float(np.mean(np.array(moved)[turning])),
            "unknown_mean": float(np.mean(unknown)),
            "anchors_created": p.tracker.created_count,
        }
    return out


def alignment(robot: PanningRobot) -> dict[str, dict[str, float]]:
    """Residual alignment error (grid pixels) of the refined lookup against the true pose's."""
    times = np.arange(RUN[0], RUN[1], 1 / FPS)
    frames = robot.frames(times)
    out = {}
    for refine in (True, False):
        p = calibrated(robot, _view(refine=refine))
        following = p.following
        assert following is not None
        for name, (pan, tilt, late) in ERRORS.items():
            errors = []
            for t, frame in zip(times, frames, strict=True):
                y = subsample(cv2.cvtColor(frame, cv2.COLOR_BGR2YCrCb), p.step)[..., 0]
                given = robot.pose(float(t) - late, math.radians(pan), math.radians(tilt))
                view = following.view(given, np.ascontiguousarray(y))
                truth = following.lookup(following.mosaic.directions, robot.pose(float(t)))
                e = np.hypot(*(view.cells - truth).transpose(2, 0, 1))[view.known]
                errors.append(float(np.median(e)))
            key = f"{name}, {'refined' if refine else 'pose only'}"
            out[key] = {
                "median_px": float(np.median(errors)),
                "p90_px": float(np.percentile(errors, 90)),
                "max_px": float(np.max(errors)),
            }
    return out


def speed(size: tuple[int, int], frames: int) -> dict[str, dict[str, float]]:
    """ms/frame of Perception.process on ``tabletop-busy`` while its objects are put down:
    the head still at pan 0 (calibrated there, without and with poses) and moving."""
    cv2.setNumThreads(1)
    times = np.arange(RUN[0], RUN[0] + frames / FPS, 1 / FPS)
    out = {}
    for name, pan, poses in (
        ("still, no poses", ((0.0, 0.0),), False),
        ("still, with poses", ((0.0, 0.0),), True),
        ("moving", PAN, True),
    ):
        robot = PanningRobot(pan, None, size)
        images = robot.frames(times)
        p = Perception(PerceptionParams(), robot.camera.width, robot.camera.height, robot.camera)
        calibration = np.linspace(*CALIBRATION, p.params.background.calibration_frames)
        robot.calibrated(p, calibration, poses)
        given = [robot.pose(float(t)) if poses else None for t in times]
        robot.close()
        ms = []
        for i, (t, image, pose) in enumerate(zip(times, images, given, strict=True)):
            start = time.perf_counter()
            p.process(image, float(t), pose)
            # The moving head's time counts only the frames in which the head turns.
            turning = pan_rate(float(t)) != 0
            if i >= 5 and (turning or pan != PAN):
                ms.append((time.perf_counter() - start) * 1000)
        out[name] = {"median_ms": float(np.median(ms)), "p90_ms": float(np.percentile(ms, 90))}
    return out


def _view(**changes: bool) -> PerceptionParams:
    return PerceptionParams(view=dataclasses.replace(ViewParams(), **changes))


def pan_rate(t: float) -> float:
    times = [k[0] for k in PAN]
    i = int(np.searchsorted(times, t, side="right"))
    if i == 0 or i >= len(PAN):
        return 0.0
    (t0, a0), (t1, a1) = PAN[i - 1], PAN[i]
    return (a1 - a0) / (t1 - t0)


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.partition("x")
    return int(w), int(h)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=_size, default=None, help="WxH of the floor runs")
    ap.add_argument("--speed-sizes", type=_size, nargs="*", default=[(176, 144), (640, 480)])
    ap.add_argument("--speed-frames", type=int, default=90)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    robot = PanningRobot(PAN, {}, args.size)
    results = {
        "floor": floor(robot),
        "alignment": alignment(robot),
        "speed": {f"{w}x{h}": speed((w, h), args.speed_frames) for w, h in args.speed_sizes},
    }
    robot.close()
    if args.json:
        print(json.dumps(results, indent=1))
        return
    print("empty floor while the head turns (fractions of the grid's pixels)")
    print(f"{'':18} {'fg mean':>8} {'fg max':>8} {'fg turn':>8} {'motion':>8} {'unknown':>8} new")
    for name, r in results["floor"].items():
        print(
            f"{name:18} {r['foreground_mean']:8.4f} {r['foreground_max']:8.4f} "
            f"{r['foreground_turning']:8.4f} {r['motion_turning']:8.4f} {r['unknown_mean']:8.4f} "
            f"{r['anchors_created']}"
        )
    print("\nresidual alignment error, grid pixels (median over a frame's known pixels)")
    for name, r in results["alignment"].items():
        print(
            f"{name:34} median {r['median_px']:.2f}  p90 {r['p90_px']:.2f}  max {r['max_px']:.2f}"
        )
    print("\nms/frame of Perception.process (median, p90; one thread)")
    for size, rows in results["speed"].items():
        for name, r in rows.items():
            print(f"{size:8} {name:36} {r['median_ms']:6.2f} {r['p90_ms']:6.2f}")


if __name__ == "__main__":
    main()
