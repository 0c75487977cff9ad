"""The marker boxes with the head moving: how many box fits are kept, and how far the kept box
poses are from fitting every search.

Reads the recorded moving-head run that ``bench/bench_daemon.py --runs folder-640-pan`` keeps
(its JPEG frames and ``joints.csv``; run that first), searches markers in every 3rd frame of the
window as the daemon does, and feeds the same markers and camera poses to two box estimators:
one as the daemon has it (a fit kept while the markers are where its boxes would be seen) and
one that fits every search. Prints, for each search the first one kept, the distance between
the two estimators' newest pose of each box (mm, degrees), the same distance between
consecutive fits of the second (how much fitting every search moves a still box's pose), and the
CPU ms a search of each estimator. ``--ticks`` rounds the joints to the servos' encoder ticks
(4096 a turn), as the daemon reads them.

    python bench/box_reuse.py [--recording DIR] [--start 240] [--frames 900] [--ticks] [--json]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from percept.kinematics.pose import wrap  # noqa: E402
from percept.perception.landmarks import boxes as boxes_module  # noqa: E402
from percept.perception.landmarks.boxes import BoxEstimator  # noqa: E402
from percept.perception.landmarks.records import BoxPose  # noqa: E402
from percept.runtime.daemon.pipeline import FrameInputs, Pipeline  # noqa: E402
from percept.runtime.settings.experiment import load_experiment  # noqa: E402
from percept.runtime.settings.profile import load_profile  # noqa: E402

FPS = 30.0
TICK = 2.0 * math.pi / 4096.0
RECORDING = Path(tempfile.gettempdir()) / "percept-bench-daemon" / "folder-640-pan-41s"


def joints(path: Path, ticks: bool) -> dict[int, dict[str, float]]:
    """The joint angles of each frame number of ``joints.csv`` (rounded to ticks if asked)."""
    out = {}
    with path.open(encoding="utf-8") as f:
        for row in csv.DictReader(f):
            angles = {k: float(v) for k, v in row.items() if k not in ("frame", "t")}
            if ticks:
                angles = {k: round(v / TICK) * TICK for k, v in angles.items()}
            out[int(row["frame"])] = angles
    return out


def newest(estimator: BoxEstimator) -> dict[int, BoxPose]:
    return {box: history[-1][1] for box, history in estimator._history.items() if history}


def apart(a: BoxPose, b: BoxPose) -> tuple[float, float]:
    """Millimetres and degrees between two poses of a box."""
    return 1000 * math.hypot(a.x - b.x, a.y - b.y), math.degrees(abs(wrap(a.theta - b.theta)))


def spread(pairs: list[tuple[float, float]]) -> dict[str, list[float]]:
    """Median, 99th percentile and largest of the millimetres and the degrees."""
    values = np.array(pairs) if pairs else np.zeros((1, 2))
    return {
        unit: [round(float(np.percentile(values[:, k], q)), 3) for q in (50, 99, 100)]
        for k, unit in enumerate(("mm", "degrees"))
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--recording", type=Path, default=RECORDING, help="bench_daemon's recording")
    p.add_argument("--start", type=int, default=240, help="first frame (after the head's sweep)")
    p.add_argument("--frames", type=int, default=900, help="frames, every 3rd searched")
    p.add_argument("--ticks", action="store_true", help="joints rounded to encoder ticks")
    p.add_argument("--json", action="store_true", help="one JSON line")
    args = p.parse_args()
    files = sorted((args.recording / "frames").glob("*.jpg"))
    if not files:
        p.error(f"no frames in {args.recording}: run bench/bench_daemon.py --runs folder-640-pan")
    angles = joints(args.recording / "joints.csv", args.ticks)
    experiment = load_experiment(ROOT / "config" / "experiments" / "tabletop.toml")
    profile = load_profile(ROOT / "config" / "robots" / "myon.toml")
    pipeline = Pipeline("a", profile, experiment, 640, 480, 0.1)  # its camera and kinematics
    kept = BoxEstimator(experiment.landmarks, pipeline.camera)
    every = BoxEstimator(experiment.landmarks, pipeline.camera)
    searches = []
    for k in range(args.start, min(args.start + args.frames, len(files)), 3):
        inputs = FrameInputs(k, k / FPS, 0.0, angles[k + 1])  # joints.csv counts from 1
        frame_pose = pipeline._frame_pose(inputs)
        assert frame_pose is not None
        image = cv2.imread(str(files[k]))
        searches.append((k / FPS, frame_pose.pose, kept.search(image, frame_pose.pose)))
    cpu = {"kept": 0.0, "every": 0.0}
    reused, consecutive = [], []
    last: dict[int, BoxPose] = {}
    tolerances = (boxes_module.SAME_CORNERS, boxes_module.SAME_VIEW)
    for t, pose, markers in searches:
        before = kept.refits_saved
        began = time.thread_time()
        kept.observe(markers, pose, t)
        cpu["kept"] += time.thread_time() - began
        added = dict(every._added)
        boxes_module.SAME_CORNERS = boxes_module.SAME_VIEW = -1.0  # every search fitted
        began = time.thread_time()
        every.observe(markers, pose, t)
        cpu["every"] += time.thread_time() - began
        boxes_module.SAME_CORNERS, boxes_module.SAME_VIEW = tolerances
        ours = newest(kept)
        fitted = {b: p for b, p in newest(every).items() if every._added[b] > added.get(b, 0)}
        if kept.refits_saved > before:
            reused += [apart(ours[b], fitted[b]) for b in fitted if b in ours]
        consecutive += [apart(last[b], fitted[b]) for b in fitted if b in last]
        last = fitted
    row = {
        "searches": len(searches),
        "kept": kept.refits_saved,
        "same_view_px": boxes_module.SAME_VIEW,
        "ticks": args.ticks,
        "kept_vs_fitted": spread(reused),
        "fit_to_fit": spread(consecutive),
        "ms_per_search": {k: round(1000 * v / len(searches), 3) for k, v in cpu.items()},
    }
    print(json.dumps(row) if args.json else json.dumps(row, indent=1))


if __name__ == "__main__":
    main()
