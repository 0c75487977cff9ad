"""Tracking while the head moves (issue 16), against the simulated truth; prints one table.

For each robot of the moving-head scenes (``tabletop-look``: a sweep, then fixations left, right
and ahead while objects change out of view; ``tabletop-pan``: a slow continuous pan), the scene
is rendered with ``percept sim`` (ground truth, joint angles per frame) and tracked:

- ``percept``: each frame's camera pose from the recorded joint angles through the profile's
  kinematics, as ``percept track SEQ --robot PROFILE`` does; the background calibrated on the
  frames of the head's sweep over the empty floor;
- ``percept, 1 deg joint error``: every joint angle 1 degree off (a constant encoder error);
- ``percept, joints 20 ms late``: each frame's pose from the angles 20 ms before it;
- ``percept, no compensation``: the same frames without poses (a still camera, the background
  calibrated on the sweep all the same): what the head motion costs without following it;
- ``MOG2 + Kalman``: OpenCV MOG2 and a Kalman blob tracker (``bench/baseline.py``), learning on
  the sweep frames.

Columns: MOTA and IDF1 (``percept.perception.evaluation.tracking``); anchors (tracks) created per
true object; the share of returns into view that got their old id back (an absence of at least
0.5 s, found again within 1 s); the median error of the ground positions percept gives (the
world model's x, y from the anchor's box and the frame's pose), as % of the object's distance,
over the frames in which the head turns faster than 0.05 rad/s; and the median ms of perception
per frame with the head moving and still (one thread; the frames after the sweep).

    MUJOCO_GL=egl python bench/bench_moving_head.py [--scenes tabletop-look tabletop-pan]
        [--robots a b] [--seconds T] [--myon] [--keep DIR] [--methods NAME ...]
        [--set KEY=VALUE ...]

``--keep DIR`` renders each sequence into DIR once and reads it back from there on later runs
(the same scene, robot and seconds); ``--methods`` runs only the named methods (``percept``,
``1deg``, ``late``, ``nocomp``, ``mog2``).

``--myon`` puts the robots of ``tabletop-myon`` into the scenes (640x480: the speed target).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from percept.kinematics.camera import CameraModel, load_intrinsics  # noqa: E402
from percept.kinematics.pose import CameraPose  # noqa: E402
from percept.kinematics.tree import KinematicTree  # noqa: E402
from percept.perception.evaluation.moving_head import (  # noqa: E402
    anchors_per_object,
    frame_matches,
    reidentification,
    relative_ground_errors,
)
from percept.perception.evaluation.tracking import evaluate_tracking, mot_box, read_mot  # noqa: E402
from percept.perception.features.experience import sensory_experience  # noqa: E402
from percept.perception.params import PerceptionParams  # noqa: E402
from percept.perception.pipeline import Perception  # noqa: E402
from percept.runtime.commands._sequence import open_sequence  # noqa: E402
from percept.runtime.commands.offline import _perception_params  # noqa: E402
from percept.runtime.daemon.devices import head_sweep  # noqa: E402
from percept.runtime.settings.scene import find_scene, load_scene  # noqa: E402

MOVING = 0.05  # rad/s: frames whose head turns faster count as "head moving"
MIN_GAP = 0.5  # s out of view that make a return
GRACE = 1.0  # s after a return within which the old id must be found


@dataclass(frozen=True)
class Sequence:
    """One robot's rendered view of a scene, with everything the truth says about it."""

    name: str
    frames: list[np.ndarray]
    fps: float
    gt: np.ndarray
    times: np.ndarray
    joints: dict[str, np.ndarray]
    """Each joint's angle per frame."""
    truth: list[dict]
    camera: CameraModel
    tree: KinematicTree
    calibration: int
    """Frames of the head's sweep over the empty floor."""

    @property
    def moving(self) -> np.ndarray:
        """Per frame: the head turns faster than :data:`MOVING`."""
        speed = np.zeros(len(self.times))
        for angles in self.joints.values():
            speed = np.maximum(speed, np.abs(np.gradient(angles, self.times)))
        return speed > MOVING

    def poses(self, error: float = 0.0, delay: float = 0.0) -> list[CameraPose]:
        """Each frame's camera pose from the joint angles ``error`` radians off, read ``delay``
        seconds before the frame."""
        angles = {
            name: np.interp(self.times - delay, self.times, values) + error
            for name, values in self.joints.items()
        }
        return [
            self.tree.camera_pose({n: float(a[k]) for n, a in angles.items()})
            for k in range(len(self.times))
        ]


def myon_copy(scene: str, folder: Path) -> str:
    """``scene`` with the robots of ``tabletop-myon`` (MYON, 640x480, standing 0.85 m from the
    middle, heads tilted further down), as a file in ``folder``."""
    text = find_scene(scene).read_text(encoding="utf-8")
    for old, new in (
        ('"../robots/robotis-op3.toml"', f'"{REPO / "config" / "robots" / "myon.toml"}"'),
        ("pose = [-0.72, 0.0, 0.0]", "pose = [-0.85, 0.0, 0.0]"),
        ("pose = [0.24625, -0.67658, 1.91986]", "pose = [0.29072, -0.79874, 1.91986]"),
        ("joints.head_tilt = { offset = -0.5 }", "joints.head_tilt = { offset = -0.85 }"),
    ):
        if old not in text:
            raise SystemExit(f"--myon: {scene} does not have {old}")
        text = text.replace(old, new)
    path = folder / f"{scene}-myon.toml"
    path.write_text(text, encoding="utf-8")
    return str(path)


def render(scene: str, robot: str, out: Path, seconds: float | None) -> Sequence:
    """``percept sim`` of ``robot`` in ``scene`` into ``out`` (unless a complete rendering is
    there already), read back."""
    if not (out / "truth.jsonl").is_file():
        command = [sys.executable, "-m", "percept.runtime.cli", "sim", "--scene", scene]
        command += ["--robot", robot, "--out", str(out)]
        if seconds is not None:
            command += ["--seconds", str(seconds)]
        subprocess.run(command, cwd=REPO, check=True, capture_output=True)
    sequence = open_sequence(out)
    frames = [im for _, _, im in sequence.frames()]
    with (out / "joints.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    names = [k for k in rows[0] if k not in ("frame", "t")]
    loaded, platforms = load_scene(find_scene(scene))
    return Sequence(
        name=f"{Path(scene).stem} ({robot})",
        frames=frames,
        fps=sequence.fps,
        gt=read_mot(out / "gt" / "gt.txt"),
        times=np.array([float(r["t"]) for r in rows]),
        joints={n: np.array([float(r[n]) for r in rows]) for n in names},
        truth=[json.loads(line) for line in (out / "truth.jsonl").open(encoding="utf-8")],
        camera=load_intrinsics(out / "intrinsics.json"),
        tree=KinematicTree.from_settings(platforms[robot].kinematics),
        calibration=max(1, int(head_sweep(loaded, robot) * sequence.fps)),
    )


@dataclass
class Run:
    """One tracker's output on a sequence."""

    rows: np.ndarray
    created: int
    ms: list[float]
    ground: dict[int, dict[int, tuple[float, float]]]
    """Per frame, the ground position (x, y) percept gives each visible anchor (by number)."""


def run_percept(
    seq: Sequence, params: PerceptionParams, poses: list[CameraPose], compensate: bool
) -> Run:
    """percept over ``seq``; with ``compensate`` each frame's pose goes to perception, else it
    is used only for the anchors' ground positions (as the world model does)."""
    background = replace(params.background, calibration_frames=seq.calibration)
    h, w = seq.frames[0].shape[:2]
    perception = Perception(
        replace(params, background=background), w, h, seq.camera if compensate else None
    )
    perception.calibrate(
        seq.frames[: seq.calibration],
        None,
        poses[: seq.calibration] if compensate else None,
    )
    rows, ms, ground = [], [], {}
    for k, image in enumerate(seq.frames):
        start = cv2.getTickCount()
        result = perception.process(image, float(seq.times[k]), poses[k] if compensate else None)
        ms.append((cv2.getTickCount() - start) / cv2.getTickFrequency() * 1e3)
        ground[k + 1] = {}
        for a in result.anchors:
            if not a.visible or result.skipped:
                continue
            rows.append([k + 1, a.number, *mot_box(a.bbox), 1, -1, -1, -1])
            seen = sensory_experience(a.bbox, a.histograms, seq.camera, poses[k], pixels=a.pixels)
            if seen.on_ground and seen.x is not None and seen.y is not None:
                ground[k + 1][a.number] = (seen.x, seen.y)
    table = np.array(rows, float).reshape(-1, 10)
    return Run(table, perception.tracker.created_count, ms, ground)


def run_mog2(seq: Sequence) -> Run:
    # Imported here: the baseline needs filterpy and scipy, which the onboard install leaves
    # out, and bench_daemon.py's recorded run imports this module for myon_copy alone.
    from bench.baseline import Mog2Tracker

    h, w = seq.frames[0].shape[:2]
    alternative = Mog2Tracker(w, h)
    alternative.learn(seq.frames[: seq.calibration])
    rows, ms = [], []
    for k, image in enumerate(seq.frames):
        start = cv2.getTickCount()
        tracks = alternative.process(image)
        ms.append((cv2.getTickCount() - start) / cv2.getTickFrequency() * 1e3)
        rows += [[k + 1, number, *mot_box(box), 1, -1, -1, -1] for number, *box in tracks]
    table = np.array(rows, float).reshape(-1, 10)
    return Run(table, len(set(table[:, 1].astype(int))), ms, {})


def ground_error(seq: Sequence, run: Run) -> float:
    """Median error of the ground positions in the frames with the head moving, as a fraction
    of the distance (NaN when there are none)."""
    moving = seq.moving
    matches = frame_matches(seq.gt, run.rows)
    estimated, truth, viewpoint = [], [], []
    for frame, pairs in matches.items():
        if not moving[frame - 1]:
            continue
        record = seq.truth[frame - 1]
        objects = {o["id"]: o["ground"] for o in record["objects"]}
        for obj, anchor in pairs.items():
            if anchor in run.ground.get(frame, {}):
                estimated.append(run.ground[frame][anchor])
                truth.append(objects[obj])
                viewpoint.append(record["camera"]["t"][:2])
    if not estimated:
        return float("nan")
    return float(
        np.median(relative_ground_errors(np.array(estimated), np.array(truth), np.array(viewpoint)))
    )


def scores(seq: Sequence, method: str, run: Run) -> dict:
    h, w = seq.frames[0].shape[:2]
    tracking = evaluate_tracking(seq.gt, run.rows, image_size=(w, h))
    reid = reidentification(
        seq.gt, run.rows, min_gap=round(MIN_GAP * seq.fps), grace=round(GRACE * seq.fps)
    )
    # Timed after the sweep: its frames are the empty floor the background was learned on.
    ms = np.array(run.ms)[seq.calibration :]
    moving = seq.moving[seq.calibration :]
    return {
        "data": seq.name,
        "method": method,
        "mota": tracking.mota,
        "idf1": tracking.idf1,
        "per_object": anchors_per_object(run.created, seq.gt),
        "reid": reid.fraction,
        "returns": reid.returns,
        "ground": ground_error(seq, run) if run.ground else float("nan"),
        "ms_moving": float(np.median(ms[moving])) if moving.any() else float("nan"),
        "ms_still": float(np.median(ms[~moving])) if (~moving).any() else float("nan"),
    }


METHODS = {
    "percept": "percept",
    "1deg": "percept, 1 deg joint error",
    "late": "percept, joints 20 ms late",
    "nocomp": "percept, no compensation",
    "mog2": "MOG2 + Kalman",
}
"""The methods' short names (``--methods``) and their names in the table."""


def evaluate(seq: Sequence, base: PerceptionParams, methods: list[str]) -> Iterator[dict]:
    exact = seq.poses()
    variants = {
        "percept": lambda: (exact, True),
        "1deg": lambda: (seq.poses(error=math.radians(1.0)), True),
        "late": lambda: (seq.poses(delay=0.02), True),
        "nocomp": lambda: (exact, False),
    }
    for short in methods:
        if short == "mog2":
            yield scores(seq, METHODS[short], run_mog2(seq))
            continue
        poses, compensate = variants[short]()
        yield scores(seq, METHODS[short], run_percept(seq, base, poses, compensate))


def _num(value: float, digits: int, scale: float = 1.0) -> str:
    return "-" if not math.isfinite(value) else f"{value * scale:.{digits}f}"


def table(rows: list[dict]) -> None:
    print(
        f"{'data':22} {'method':28} {'MOTA':>7} {'IDF1':>6} {'anch/obj':>8} {'re-id %':>8}"
        f" {'ground %':>8} {'ms moving':>9} {'ms still':>8}"
    )
    for r in rows:
        reid = f"{_num(r['reid'], 0, 100)} /{r['returns']}"
        print(
            f"{r['data']:22} {r['method']:28} {_num(r['mota'], 3):>7} {_num(r['idf1'], 3):>6}"
            f" {_num(r['per_object'], 2):>8} {reid:>8} {_num(r['ground'], 2, 100):>8}"
            f" {_num(r['ms_moving'], 2):>9} {_num(r['ms_still'], 2):>8}"
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["tabletop-look", "tabletop-pan"])
    parser.add_argument("--robots", nargs="+", default=["a", "b"])
    parser.add_argument("--seconds", type=float, help="scene seconds (default: the whole scene)")
    parser.add_argument(
        "--myon", action="store_true", help="the robots of tabletop-myon: MYON's 640x480 camera"
    )
    parser.add_argument("--keep", type=Path, help="render into (and reuse) this folder")
    parser.add_argument(
        "--methods", nargs="+", choices=list(METHODS), default=list(METHODS),
        help="the methods to run (default: all)",
    )  # fmt: skip
    _perception_params.add_arguments(parser)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    base = _perception_params.params_from_args(args)
    with tempfile.TemporaryDirectory() as tmp:
        scenes = [myon_copy(s, Path(tmp)) if args.myon else s for s in args.scenes]
        folder = args.keep if args.keep is not None else Path(tmp)
        seconds = "" if args.seconds is None else f"-{args.seconds:g}s"
        sequences = (
            render(scene, robot, folder / f"{Path(scene).stem}-{robot}{seconds}", args.seconds)
            for scene in scenes
            for robot in args.robots
        )
        rows = [_dot(row) for seq in sequences for row in evaluate(seq, base, args.methods)]
    print(file=sys.stderr)
    table(rows)
    return 0


def _dot(row: dict) -> dict:
    """``row``, with a dot on stderr for progress."""
    print(".", end="", file=sys.stderr, flush=True)
    return row


if __name__ == "__main__":
    sys.exit(main())
