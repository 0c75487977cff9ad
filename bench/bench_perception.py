"""Perception speed: percept's pipeline against OpenCV MOG2 + a Kalman blob tracker.

Both run on the same pre-rendered frames of a synthetic table-top scene with 8 objects in view
(four still, four moving and crossing the still ones, see
``percept.perception.evaluation.synthetic.busy_scene``), in one process, with
``cv2.setNumThreads(1)``, frame by frame in turn so that both see the same machine load. Decoding
and rendering are not timed. For each resolution it prints ms/frame (median and p90) of wall-clock
time and of the thread's CPU time, and the ratio of the medians.

A third column times the passes over every pixel (of the grid) that percept's pipeline makes
each frame, all of them single OpenCV calls: colour conversion, foreground test and opening,
motion test and closing. Nothing done per region or per object is in it, so it is
the floor of the pipeline's time as long as those calls are OpenCV's.

The per-region and per-object steps are compiled kernels (``percept.perception.compiled``); the
first ``WARMUP`` frames, not timed, also load them from numba's cache (or compile them).

The moving-head case (issue 20) runs in the same process after the comparison, at each size, on
a scene whose frames come with camera poses: robot a of ``tabletop-busy`` (MuJoCo, rendered
before the timing) while its objects are put down, its head held at pan 0 (``still_head``: no
poses, what a still camera costs; ``still_head_poses``: calibrated there with poses and given
each frame's pose, as the daemon does, which adds the anchors' ground positions and memory) or
turning to 0, -0.3, 0.3 and 0 rad after sweeping its working range for the calibration
(``moving_head``: ``Perception.process(image, t, pose)`` with the pose from forward kinematics;
the pan keyframes of ``bench/bench_following.py``), at 30 fps. The three pipelines take their
frames in turn; only the frames in which the head turns count for the moving head.
``moving_head_ratio`` is moving / still without poses (median ms), ``moving_head_poses_ratio``
moving / still with poses; the ``cpu`` keys the same of the thread's CPU time. ``--no-moving``
leaves the case out (it needs MuJoCo rendering: ``MUJOCO_GL=egl``).

``--steps`` times instead each step of ``Perception.process`` on its own (percept alone, no MOG2
between its frames): a timer around every call the pipeline makes to the step's function, the
median µs per frame of each. The ``light:`` rows are the light adaptation's steps (on by
default), which make about half of a still camera's frame. ``--head-steps`` does the same for
the steps of the moving-head case (:data:`HEAD_STEPS`), the head still (no poses) and moving:
the mean CPU µs of the thread per frame (some steps run only in some frames; CPU time, so that
a frame in which the thread waited for a core does not count) over the frames of
:func:`run_heads`.

    python bench/bench_perception.py [--frames 400] [--sizes 176x144 640x480] [--json] [--steps]
        [--no-moving] [--head-steps] [--params PRESET|TOML] [--set KEY=VALUE ...]

``--params`` and ``--set`` change percept's parameters for the percept rows of the table (as for
``percept track``; ``--steps`` and ``--head-steps`` keep the defaults).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.baseline import Mog2Tracker  # noqa: E402
from percept.perception.colour import to_ycrcb  # noqa: E402
from percept.perception.evaluation.synthetic import busy_scene  # noqa: E402
from percept.perception.params import PerceptionParams  # noqa: E402
from percept.perception.pipeline import Perception  # noqa: E402
from percept.perception.segmentation.labelling.regions import subsample  # noqa: E402
from percept.perception.tracking.motion import MotionDetector, open_mask  # noqa: E402
from percept.runtime.commands.offline import _perception_params  # noqa: E402

CALIBRATION_FRAMES = 30
WARMUP = 20
PIPELINES = ("percept", "mog2", "pixels")
HEADS = ("still_head", "still_head_poses", "moving_head")
HEAD_FPS = 30.0


class PixelPasses:
    """The whole-image OpenCV calls of :meth:`Perception.process`, and nothing else."""

    def __init__(self, percept: Perception) -> None:
        self.percept = percept
        params = percept.params
        self.motion = MotionDetector(
            percept.grid_background, params.motion.k, params.regions.opening, percept.step
        )

    def process(self, frame_bgr: np.ndarray) -> None:
        p = self.percept
        ycc = to_ycrcb(subsample(frame_bgr, p.step))
        open_mask(p.grid_background.classify(ycc), p.kernel)
        self.motion.update(ycc).mask()


def run(width: int, height: int, frames: int, params: PerceptionParams) -> dict[str, float]:
    """Time both pipelines on one scene; ms/frame statistics."""
    scene = busy_scene(width, height, frames)
    empty = scene.empty(CALIBRATION_FRAMES)
    images = [scene.render(i) for i in range(frames)]
    percept = Perception(params, width, height)
    percept.calibrate(empty)
    alternative = Mog2Tracker(width, height)
    alternative.learn(empty)
    floor = PixelPasses(percept)
    wall: dict[str, list[float]] = {name: [] for name in PIPELINES}
    cpu: dict[str, list[float]] = {name: [] for name in PIPELINES}
    in_view = []

    def timed(name: str, step, *args):
        w0, c0 = time.perf_counter(), time.thread_time()
        out = step(*args)
        w1, c1 = time.perf_counter(), time.thread_time()
        if len(in_view) > WARMUP:
            wall[name].append(w1 - w0)
            cpu[name].append(c1 - c0)
        return out

    for i, image in enumerate(images):
        result = timed("percept", percept.process, image, i / 25.0)
        timed("mog2", alternative.process, image)
        timed("pixels", floor.process, image)
        in_view.append(sum(a.visible for a in result.anchors))
    row: dict[str, float] = {"width": width, "height": height, "frames": frames}
    for name in PIPELINES:
        w, c = np.array(wall[name]) * 1e3, np.array(cpu[name]) * 1e3
        row[f"{name}_ms_median"] = float(np.median(w))
        row[f"{name}_ms_p90"] = float(np.percentile(w, 90))
        row[f"{name}_cpu_ms_median"] = float(np.median(c))
        row[f"{name}_cpu_ms_p90"] = float(np.percentile(c, 90))
    row["ratio"] = row["mog2_ms_median"] / row["percept_ms_median"]
    row["cpu_ratio"] = row["mog2_cpu_ms_median"] / row["percept_cpu_ms_median"]
    row["pixels_share"] = row["pixels_ms_median"] / row["percept_ms_median"]
    row["objects_in_view"] = len(scene.blobs)
    row["anchors_visible_median"] = float(np.median(in_view[WARMUP:]))
    return row


def run_heads(width: int, height: int, frames: int, params: PerceptionParams) -> dict[str, float]:
    """ms/frame of percept with the head still and moving (``frames`` at most, at
    :data:`HEAD_FPS` from the end of the calibration sweep); the moving head's time over the
    frames in which it turns."""
    from bench.bench_following import CALIBRATION, PAN, RUN, pan_rate
    from tests.support.moving_head import PanningRobot

    times = np.arange(RUN[0], RUN[1], 1 / HEAD_FPS)[:frames]
    runs = {}
    still = ((0.0, 0.0),)
    for name, pan, poses in (
        ("still_head", still, False),
        ("still_head_poses", still, True),
        ("moving_head", PAN, True),
    ):
        robot = PanningRobot(pan, None, (width, height))
        percept = Perception(params, width, height, robot.camera)
        calibration = np.linspace(*CALIBRATION, percept.params.background.calibration_frames)
        robot.calibrated(percept, calibration, poses)
        given = [robot.pose(float(t)) if poses else None for t in times]
        runs[name] = (percept, robot.frames(times), given)
        robot.close()
    wall: dict[str, list[float]] = {name: [] for name in HEADS}
    cpu: dict[str, list[float]] = {name: [] for name in HEADS}
    for i, t in enumerate(times.tolist()):
        turning = pan_rate(t) != 0
        for name, (percept, images, given) in runs.items():
            w0, c0 = time.perf_counter(), time.thread_time()
            percept.process(images[i], t, given[i])
            w1, c1 = time.perf_counter(), time.thread_time()
            if i >= WARMUP and (turning or name != "moving_head"):
                wall[name].append(w1 - w0)
                cpu[name].append(c1 - c0)
    row: dict[str, float] = {}
    for name in HEADS:
        w, c = np.array(wall[name]) * 1e3, np.array(cpu[name]) * 1e3
        row[f"{name}_ms_median"] = float(np.median(w))
        row[f"{name}_ms_p90"] = float(np.percentile(w, 90))
        row[f"{name}_cpu_ms_median"] = float(np.median(c))
        row[f"{name}_frames"] = len(w)
    for still, key in (("still_head", "moving_head"), ("still_head_poses", "moving_head_poses")):
        for kind in ("", "_cpu"):
            moving = row[f"moving_head{kind}_ms_median"]
            row[f"{key}{kind}_ratio"] = moving / row[f"{still}{kind}_ms_median"]
    return row


STEPS = {
    "taking the grid": ("segmentation.grid_frame", None, "subsample"),
    "colour conversion": ("segmentation.grid_frame", None, "to_ycrcb"),
    "foreground test": ("segmentation.background", "BackgroundModel", "classify"),
    "opening": ("backgrounds", None, "open_mask"),
    "Kalman predict": ("tracking.anchors", "AnchorTracker", "predict"),
    "regions and split (one kernel)": ("segmentation.segment", "Segmenter", "__call__"),
    "motion in boxes (outside the next)": ("tracking.motion", "Motion", "fraction"),
    "anchors: motion, association, correction (kernel)": ("tracking.anchors", None, "track"),
    "anchor records": ("tracking.anchors", "AnchorTracker", "anchors"),
    "anchors: update in all": ("tracking.anchors", "AnchorTracker", "update"),
    "light: boxes, fit, compensation, test, shadows (kernel)": (
        "light.adaptation",
        None,
        "light_frame",
    ),
    "light: ghosts when due, marks (labelling + kernel)": ("light.adaptation", None, "light_after"),
    "light: foreground in all": ("light.adaptation", "LightAdaptation", "foreground"),
    "light: maintenance": ("light.adaptation", "LightAdaptation", "maintain"),
    "frame in all": ("pipeline", "Perception", "process"),
}
"""Each step: the module of ``percept.perception`` (and class) where the pipeline finds it."""


def steps(sizes: list[tuple[int, int]], frames: int) -> dict[tuple[int, int], dict[str, float]]:
    """Median µs per frame of each step of :data:`STEPS` at each size, percept alone."""
    import importlib

    spent: dict[str, list[float]] = {name: [] for name in STEPS}

    def timed(name: str, function):
        def step(*args, **kwargs):
            t0 = time.perf_counter()
            out = function(*args, **kwargs)
            spent[name].append(time.perf_counter() - t0)
            return out

        return step

    for name, (module, cls, attribute) in STEPS.items():
        owner = importlib.import_module(f"percept.perception.{module}")
        owner = owner if cls is None else getattr(owner, cls)
        setattr(owner, attribute, timed(name, getattr(owner, attribute)))
    out = {}
    for width, height in sizes:
        scene = busy_scene(width, height, frames)
        images = [scene.render(i) for i in range(frames)]  # as in run(): frames not in the cache
        percept = Perception(PerceptionParams(), width, height)
        percept.calibrate(scene.empty(CALIBRATION_FRAMES))
        for i, image in enumerate(images):
            if i == WARMUP:
                for times in spent.values():
                    times.clear()
            percept.process(image, i / 25.0)
        out[(width, height)] = {
            n: float(np.median(t)) * 1e6 if t else 0.0 for n, t in spent.items()
        }
    return out


HEAD_STEPS = {
    "frame in all": [("pipeline", "Perception", "process")],
    "light adaptation (foreground)": [
        ("light.adaptation", "LightAdaptation", "foreground"),
        ("light.adaptation", "LightAdaptation", "view_foreground"),
    ],
    "foreground test": [
        ("segmentation.background", "BackgroundModel", "classify"),
        ("view.follow", "FrameView", "classify"),
    ],
    "background into the view": [("view.follow", "FollowingBackground", "view")],
    "  lookup of the map coordinates (lattice)": [("view.map.directions", "Lookup", "coarse")],
    "  bounds of the view (kernel)": [("view.follow", "FollowingBackground", "_view_of")],
    "  alignment (phase correlation)": [("view.follow", "FollowingBackground", "_shift")],
    "previous frame into the view (warp)": [
        ("tracking.motion", None, "warp_boxes"),
        ("tracking.motion", None, "warp_near"),
        ("tracking.motion", None, "warp_all"),
    ],
    "regions and split (one kernel)": [("segmentation.segment", "Segmenter", "__call__")],
    "motion in boxes": [("tracking.motion", "Motion", "fraction")],
    "Kalman predict (+ boxes into the view)": [("tracking.anchors", "AnchorTracker", "predict")],
    "anchors: update in all": [("tracking.anchors", "AnchorTracker", "update")],
    "  anchors' memory (ground positions)": [
        ("tracking.permanence.memory", "AnchorMemory", "follow")
    ],
    "learning unknown directions": [("backgrounds", "ViewBackground", "learn")],
    "  directions last background (ghosts)": [("view.ghosts", "ViewGhosts", "mark")],
    "  ghost test": [("view.ghosts", "ViewGhosts", "test")],
    "  unknown directions learned": [("view.mosaic", "ViewMosaic", "learn")],
}
"""The steps of the moving-head case: the functions (module of ``percept.perception``, class,
name) whose time each counts."""


def head_steps(sizes: list[tuple[int, int]], frames: int) -> dict[tuple[int, int], dict]:
    """Mean CPU µs per frame of each step of :data:`HEAD_STEPS` at each size, the head still
    (no poses) and moving (the frames in which it turns)."""
    import importlib

    from bench.bench_following import CALIBRATION, PAN, RUN, pan_rate
    from tests.support.moving_head import PanningRobot

    frame: dict[str, float] = {}

    def timed(name: str, function):
        def step(*args, **kwargs):
            t0 = time.thread_time()
            out = function(*args, **kwargs)
            frame[name] = frame.get(name, 0.0) + time.thread_time() - t0
            return out

        return step

    for name, places in HEAD_STEPS.items():
        for module, cls, attribute in places:
            owner = importlib.import_module(f"percept.perception.{module}")
            owner = owner if cls is None else getattr(owner, cls)
            setattr(owner, attribute, timed(name, getattr(owner, attribute)))
    out = {}
    times = np.arange(RUN[0], RUN[1], 1 / HEAD_FPS)[:frames]
    for width, height in sizes:
        out[(width, height)] = {}
        for head, pan in (("still", ((0.0, 0.0),)), ("moving", PAN)):
            robot = PanningRobot(pan, None, (width, height))
            percept = Perception(PerceptionParams(), width, height, robot.camera)
            calibration = np.linspace(*CALIBRATION, percept.params.background.calibration_frames)
            robot.calibrated(percept, calibration, head == "moving")
            images = robot.frames(times)
            given = [robot.pose(float(t)) if head == "moving" else None for t in times]
            robot.close()
            spent: list[dict[str, float]] = []
            for i, t in enumerate(times.tolist()):
                frame.clear()
                percept.process(images[i], t, given[i])
                if i >= WARMUP and (head == "still" or pan_rate(t) != 0):
                    spent.append(dict(frame))
            out[(width, height)][head] = {
                n: 1e6 * sum(f.get(n, 0.0) for f in spent) / len(spent) for n in HEAD_STEPS
            }
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=400)
    parser.add_argument("--sizes", nargs="+", default=["176x144", "640x480"])
    parser.add_argument("--json", action="store_true", help="one JSON line per size")
    parser.add_argument("--steps", action="store_true", help="µs per step of percept alone")
    parser.add_argument("--no-moving", action="store_true", help="without the moving-head case")
    parser.add_argument(
        "--head-steps", action="store_true", help="µs per step, the head still and moving"
    )
    _perception_params.add_arguments(parser)  # percept's parameters (the table's rows)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    if args.head_steps:
        sizes = [(int(w), int(h)) for w, h in (size.split("x") for size in args.sizes)]
        heads = head_steps(sizes, args.frames)
        print(f"percept alone, mean CPU µs per frame, load average {os.getloadavg()[0]:.1f}")
        print(f"{'step':42}" + "".join(f"{f'{w}x{h} still':>16}{'moving':>8}" for w, h in sizes))
        for name in HEAD_STEPS:
            cells = "".join(
                f"{heads[z]['still'][name]:>16.1f}{heads[z]['moving'][name]:>8.1f}" for z in sizes
            )
            print(f"{name:42}" + cells)
        return 0
    if args.steps:
        sizes = [(int(w), int(h)) for w, h in (size.split("x") for size in args.sizes)]
        table = steps(sizes, args.frames)
        print(f"percept alone, median µs per frame, load average {os.getloadavg()[0]:.1f}")
        print(f"{'step':50}" + "".join(f"{f'{w}x{h}':>10}" for w, h in sizes))
        for name in STEPS:
            print(f"{name:50}" + "".join(f"{table[size][name]:>10.1f}" for size in sizes))
        return 0
    params = _perception_params.params_from_args(args)
    rows = [run(*map(int, size.split("x")), args.frames, params) for size in args.sizes]
    if not args.no_moving:
        for row in rows:
            row.update(run_heads(int(row["width"]), int(row["height"]), args.frames, params))
    if args.json:
        for row in rows:
            print(json.dumps(row))
        return 0
    print(f"one thread, {args.frames} frames, load average {os.getloadavg()[0]:.1f}")
    print(
        f"{'size':>9} | {'percept ms median/p90':>21} | {'MOG2+Kalman ms median/p90':>25} | "
        f"{'ratio':>5} | {'CPU ms percept / MOG2':>21} | {'ratio':>5} | "
        f"{'pixel passes ms (share)':>23} | anchors"
    )
    for r in rows:
        print(
            f"{r['width']:>4}x{r['height']:<4} | "
            f"{r['percept_ms_median']:>10.3f} / {r['percept_ms_p90']:<8.3f} | "
            f"{r['mog2_ms_median']:>12.3f} / {r['mog2_ms_p90']:<10.3f} | {r['ratio']:>5.1f} | "
            f"{r['percept_cpu_ms_median']:>9.3f} / {r['mog2_cpu_ms_median']:<9.3f} | "
            f"{r['cpu_ratio']:>5.1f} | "
            f"{r['pixels_ms_median']:>15.3f} ({r['pixels_share']:>4.0%}) | "
            f"{r['anchors_visible_median']:.0f}/{r['objects_in_view']}"
        )
    if args.no_moving:
        return 0
    print("\nhead still / moving (tabletop-busy robot a, 30 fps; moving: the frames it turns in)")
    print(
        f"{'size':>9} | {'still ms median/p90':>19} | {'still, poses':>17} | "
        f"{'moving ms median/p90':>20} | moving / still, / still with poses | the same by CPU"
    )
    for r in rows:
        print(
            f"{r['width']:>4}x{r['height']:<4} | "
            f"{r['still_head_ms_median']:>8.3f} / {r['still_head_ms_p90']:<8.3f} | "
            f"{r['still_head_poses_ms_median']:>7.3f} / {r['still_head_poses_ms_p90']:<7.3f} | "
            f"{r['moving_head_ms_median']:>9.3f} / {r['moving_head_ms_p90']:<8.3f} | "
            f"{r['moving_head_ratio']:>15.2f}x, {r['moving_head_poses_ratio']:.2f}x | "
            f"{r['moving_head_cpu_ratio']:.2f}x, {r['moving_head_poses_cpu_ratio']:.2f}x"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
