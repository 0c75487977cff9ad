"""Anchors while the head moves, and object permanence, measured on rendered frames of known truth.

Boxes on a uniform floor (``percept.perception.evaluation.cubes``: the background model holds
at every head pose, so this measures the anchors alone, not the background model), 176x144 at
10 frames a second, the camera 0.4 m up and tilted 0.6 rad down. Two experiments, each run with
the camera poses given to perception (compensation and memory on) and without (a still camera,
as before issue 16):

- **saccades**: three boxes ahead; the head turns by ``A`` radians in one frame and back two
  seconds later. Anchors created per true object (1.0 is one anchor for each).
- **look away**: three boxes ahead; the head turns 1 rad to the right for 10 s (out of view of
  all three; a fourth box is seen there), then back. Meanwhile one box stays, one is moved by
  3-10 cm and one is taken away. Counted: the returns that get their old id (the box that stayed,
  the one moved), and the boxes taken away whose anchor is gone within 2 s of looking back.

Also the median ms per frame of ``Perception.process`` in both runs (one thread). With ``--sim
SEQ``, a sequence written by ``percept sim`` with still heads (``percept sim --scene
tabletop-busy --robot a --out busy``) is tracked with its camera poses (``truth.jsonl``) and
without: MOTA, IDF1, anchors created, and in how many frames the visible anchors differ.

    python bench/permanence.py [--trials 20] [--sim busy]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from percept.kinematics.camera import CameraModel, load_intrinsics  # noqa: E402
from percept.kinematics.pose import CameraPose  # noqa: E402
from percept.perception.evaluation.cubes import Cube, head_pose, matched_id, render  # noqa: E402
from percept.perception.evaluation.tracking import (  # noqa: E402
    evaluate_tracking,
    iou,
    mot_box,
    read_mot,
)
from percept.perception.params import PerceptionParams  # noqa: E402
from percept.perception.pipeline import FrameResult, Perception  # noqa: E402
from percept.runtime.commands._sequence import open_sequence  # noqa: E402

W, H, FPS = 176, 144, 10.0
CAMERA = CameraModel.from_opening_angles(math.radians(60), math.radians(47), W, H)
COLOURS = [(40, 40, 220), (40, 190, 40), (220, 60, 40), (30, 210, 230), (200, 40, 200)]


def layout(
    rng: np.random.Generator, n: int, lo: float = -0.38, hi: float = 0.38
) -> list[tuple[float, float]]:
    """``n`` places ahead of the robot, between bearings ``lo`` and ``hi`` (radians, left
    positive), whose boxes are at least 4 pixels apart in the image when looking ahead."""
    while True:
        places = []
        for _ in range(n):
            bearing, reach = rng.uniform(lo, hi), rng.uniform(0.45, 0.75)
            places.append((reach * math.cos(bearing), reach * math.sin(bearing)))
        _, boxes = render([Cube(COLOURS[0], *p) for p in places], 0, CAMERA, head_pose(0.0), rng)
        if all(b is not None for b in boxes) and _apart(np.array(boxes, float), 4.0):
            return places


def _apart(boxes: np.ndarray, gap: float) -> bool:
    grown = boxes + np.array([-gap / 2, -gap / 2, gap, gap])
    overlaps = iou(grown, grown)
    return bool((overlaps[~np.eye(len(boxes), dtype=bool)] == 0).all())


def process(cubes: list[Cube], pans: list[float], with_poses: bool):
    """Results, true boxes per frame and median ms per frame."""
    rng = np.random.default_rng(7)
    perception = Perception(PerceptionParams(), W, H, CAMERA)
    perception.calibrate([render([], 0, CAMERA, head_pose(0.0), rng)[0] for _ in range(30)])
    results: list[FrameResult] = []
    truth, ms = [], []
    for f, pan in enumerate(pans):
        image, boxes = render(cubes, f, CAMERA, head_pose(pan), rng)
        began = time.perf_counter()
        results.append(perception.process(image, f / FPS, head_pose(pan) if with_poses else None))
        ms.append((time.perf_counter() - began) * 1e3)
        truth.append(boxes)
    return perception, results, truth, float(np.median(ms))


def ids_of(results, truth, cube: int, frames) -> set[str]:
    return {i for f in frames if (i := matched_id(results[f].anchors, truth[f][cube])) is not None}


def saccades(trials: int) -> None:
    print("saccades: anchors created per true object (3 boxes; turn and back in one frame)")
    header = ("turn (rad)", "pixels", "with poses", "without", "ms with", "ms w/o")
    print(" ".join(f"{h:>11}" for h in header))
    for amplitude in (0.1, 0.2, 0.3, 0.4):
        pans = [0.0] * 20 + [amplitude] * 20 + [0.0] * 20
        per: dict[bool, list[float]] = {True: [], False: []}
        ms: dict[bool, list[float]] = {True: [], False: []}
        for trial in range(trials):
            rng = np.random.default_rng(trial)
            places = layout(rng, 3, amplitude - 0.45, 0.42)  # all in view after the turn
            cubes = [Cube(COLOURS[i], *p) for i, p in enumerate(places)]
            for with_poses in (True, False):
                perception, _, _, m = process(cubes, pans, with_poses)
                per[with_poses].append(perception.tracker.created_count / 3)
                ms[with_poses].append(m)
        pixels = CAMERA.fx * math.tan(amplitude)
        row = (f"{amplitude:.1f}", f"{pixels:.0f}", f"{np.mean(per[True]):.2f}")
        row += (f"{np.mean(per[False]):.2f}", f"{np.median(ms[True]):.2f}")
        row += (f"{np.median(ms[False]):.2f}",)
        print(" ".join(f"{c:>11}" for c in row))


def look_away(trials: int) -> None:
    away_s, back_at = 10.0, 20 + 2 + 100
    pans = [0.0] * 20 + [-0.5, -1.0] + [-1.0] * int(away_s * FPS) + [-0.5, 0.0] + [0.0] * 30
    back = back_at + 2
    counts = {True: np.zeros(4), False: np.zeros(4)}
    for trial in range(trials):
        rng = np.random.default_rng(100 + trial)
        (a, b, c) = layout(rng, 3)
        angle = rng.uniform(0, 2 * math.pi)
        shift = rng.uniform(0.03, 0.10)
        moved = (shift * math.cos(angle), shift * math.sin(angle))
        cubes = [
            Cube(COLOURS[0], *a),
            Cube(COLOURS[1], *b, moved_at=60, moved=moved),
            Cube(COLOURS[2], *c, stop=60),
            Cube(COLOURS[3], 0.5, -0.6),
        ]
        for with_poses in (True, False):
            _, results, truth, _ = process(cubes, pans, with_poses)
            before = [ids_of(results, truth, i, range(10, 20)) for i in range(3)]
            after = [ids_of(results, truth, i, range(back + 3, len(pans))) for i in range(2)]
            taken = next(iter(before[2]), None)
            gone = taken is not None and all(
                all(x.id != taken for x in results[f].anchors) for f in range(back + 20, len(pans))
            )
            counts[with_poses] += [
                after[0] == before[0] and len(before[0]) == 1,
                after[1] == before[1] and len(before[1]) == 1,
                gone,
                1,
            ]
    print(f"\nlook away for {away_s:g} s ({trials} trials): share of")
    print(f"{'':>12} {'stayed: old id':>15} {'moved: old id':>14} {'taken: dropped':>15}")
    for with_poses, name in ((True, "with poses"), (False, "without")):
        stayed, moved_ok, dropped, n = counts[with_poses]
        print(f"{name:>12} {stayed / n:>15.2f} {moved_ok / n:>14.2f} {dropped / n:>15.2f}")


def still_sim(folder: Path) -> None:
    """The sequence tracked with its (still) camera poses and without."""
    camera = load_intrinsics(folder / "intrinsics.json")
    with (folder / "truth.jsonl").open(encoding="utf-8") as fh:
        poses = [CameraPose.from_dict(json.loads(line)["camera"]) for line in fh]
    sequence = open_sequence(folder)
    frames = [im for _, _, im in sequence.frames()]
    gt = read_mot(folder / "gt" / "gt.txt")
    calibration = int(2 * sequence.fps)
    seen: dict[bool, list[list[tuple]]] = {}
    print(f"\nstill heads, {folder} ({len(frames)} frames):")
    for with_poses in (True, False):
        perception = Perception(PerceptionParams(), camera.width, camera.height, camera)
        perception.calibrate(frames[:calibration])
        rows, seen[with_poses] = [], []
        for f, image in enumerate(frames):
            at = poses[f] if with_poses else None
            result = perception.process(image, f / sequence.fps, at)
            visible = [(a.id, a.bbox) for a in result.anchors if a.visible]
            seen[with_poses].append(visible)
            rows += [
                [f + 1, a.number, *mot_box(a.bbox), 1, -1, -1, -1]
                for a in result.anchors
                if a.visible
            ]
        scores = evaluate_tracking(gt, np.array(rows, float).reshape(-1, 10))
        name = "with poses" if with_poses else "without"
        print(
            f"{name:>12}: MOTA {scores.mota:.3f}, IDF1 {scores.idf1:.3f}, anchors created "
            f"{perception.tracker.created_count}"
        )
    differ = sum(a != b for a, b in zip(seen[True], seen[False], strict=True))
    print(f"frames whose visible anchors differ: {differ} of {len(frames)}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--sim", type=Path, metavar="SEQ", help="a still-head percept sim output")
    args = parser.parse_args()
    if args.sim is not None:
        still_sim(args.sim)
    saccades(args.trials)
    look_away(args.trials)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
