"""Robustness over a distribution of scenes: draw them, render, track and score each for every
robot with the commands a lab would use, and report the distribution of the scores.

For each seed ``S`` .. ``S + N - 1``:

    percept scenarios --count N --seed S --out OUT/scenes [--distribution FILE]
    percept sim --scene OUT/scenes/NAME.toml --robot R --out SEQ --fps FPS
    percept track SEQ --robot PROFILE --out OUT/tracks/NAME-R.txt

(``percept track`` takes the number of calibration frames from the folder.) Per scene and robot:
MOTA and IDF1 (``percept.perception.evaluation.tracking``), anchors created per true object,
and persistent false anchors: anchors that were in view but matched to no true object (IoU 0.5,
the frame's one-to-one pairing) for more than ``--persistent`` seconds in all
(``percept.perception.evaluation.false_anchors``), and where the errors come from: counts of
missed objects, false boxes, boxes too big (objects merged) and boxes on a part (objects cut)
(``percept.perception.evaluation.error_classes``). Each result is
written as it comes (``OUT/results/NAME-R.json``) and a run started again skips what is done, so a
run cut short still reports what it has; ``--report`` only aggregates what is there.

The distribution over all (scene, robot) pairs: median, 10th percentile and minimum of MOTA,
the three worst with their scene files, the 90th percentile of anchors per object and the share
of pairs without a persistent false anchor, against the targets; the error classes' shares of
all true boxes. Written as ``OUT/robustness.json``
and drawn as ``OUT/robustness.png`` (every pair's MOTA sorted, with the targets); prints the table
and every pair's error classes.

    MUJOCO_GL=egl python bench/robustness.py --count 60 --seed 1 --jobs 2 --out OUT
        [--distribution FILE] [--fps 15] [--keep] [--report]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from percept.config.loader import load  # noqa: E402
from percept.drivers.sim.scenarios.draw import FLOOR_LIKE  # noqa: E402
from percept.drivers.sim.scene import Scene  # noqa: E402
from percept.perception.evaluation.error_classes import (  # noqa: E402
    NONE,
    ErrorClasses,
    error_classes,
)
from percept.perception.evaluation.false_anchors import false_seconds, persistent  # noqa: E402
from percept.perception.evaluation.moving_head import anchors_per_object  # noqa: E402
from percept.perception.evaluation.tracking import (  # noqa: E402
    clip_boxes,
    evaluate_tracking,
    ignoring,
    iou,
    read_mot,
)
from percept.perception.tracking.permanence.memory import covered  # noqa: E402
from percept.runtime.commands.offline import _perception_params as perception_params  # noqa: E402
from percept.runtime.settings.scene import robot_profile  # noqa: E402

PERCEPT = [sys.executable, "-m", "percept.runtime.cli"]
TARGETS = {
    "mota_median": 0.97,
    "mota_p10": 0.90,
    "mota_min": 0.80,
    "anchors_per_object_p90": 1.1,
    "share_without_persistent_false": 0.90,
}


@dataclass(frozen=True)
class Result:
    """The scores of one robot's view of one scene."""

    scene: str
    file: str
    robot: str
    frames: int
    mota: float
    idf1: float
    anchors_per_object: float
    persistent_false_anchors: int
    longest_false_seconds: float
    seconds: float
    errors: dict[str, int] = field(default_factory=dict)
    """Counts of :class:`ErrorClasses` (empty in results written before they were counted)."""
    floor_like_share: float | None = None
    """Share of the true boxes that are of objects of the floor's colour (:func:`floor_like`);
    None in results written before it was counted."""
    mota_floor_like_ignored: float | None = None
    """MOTA with those objects ignored (a box on one, :func:`off`, is neither a hit nor a false
    box)."""


def floor_like(scene: Scene) -> list[int]:
    """Ids of the scene's objects whose colour is the floor's: every channel within
    ``FLOOR_LIKE`` levels of the floor's colour, the range the generator draws floor-like objects
    from (whichever kind of colour the object was drawn as). The background test's per-pixel
    bound is wider than that (5 deviations of at least 3 levels), so such an object stands out,
    if at all, by its shading alone."""
    floor = np.array(scene.floor.color, float)
    return [
        o.id for o in scene.objects if np.abs(np.array(o.color, float) - floor).max() <= FLOOR_LIKE
    ]


ON_ONE = 0.5
"""Share of an anchor box inside an ignored object's box that makes it a box on that object."""


def off(gt: np.ndarray, hyp: np.ndarray, ids: Sequence[int], size: tuple[int, int]) -> np.ndarray:
    """``hyp`` less the anchor boxes on the objects ``ids``: at least ``ON_ONE`` of the box
    inside one of theirs in its frame, and paired with no other object at IoU 0.5. The ignore
    rule of the scoring takes only a box that pairs with an ignored object at IoU 0.5; an
    anchor on the lit part of an object of the floor's colour, the rest of it unseen, is on it
    too."""
    keep = np.ones(len(hyp), bool)
    of_them = np.isin(gt[:, 1].astype(int), ids)
    ignored, counted = gt[of_them], gt[~of_them]
    for f in np.unique(ignored[:, 0]):
        rows = np.flatnonzero(hyp[:, 0] == f)
        if not len(rows):
            continue
        boxes = hyp[rows, 2:6]
        on = covered(boxes, clip_boxes(ignored[ignored[:, 0] == f, 2:6], size)).max(axis=1)
        scored = counted[counted[:, 0] == f]
        if len(scored):
            paired = iou(boxes, clip_boxes(scored[:, 2:6], size)).max(axis=1) >= 0.5
            on = np.where(paired, 0.0, on)
        keep[rows[on >= ON_ONE]] = False
    return hyp[keep]


def floor_like_scores(
    scene: Scene, gt: np.ndarray, hyp: np.ndarray, size: tuple[int, int]
) -> tuple[float, float | None]:
    """(share of the true boxes of floor-coloured objects, MOTA with them ignored: None where
    every true box is of one)."""
    ids = floor_like(scene)
    share = float(np.isin(gt[:, 1].astype(int), ids).mean()) if len(gt) else 0.0
    mota = evaluate_tracking(ignoring(gt, ids), off(gt, hyp, ids, size), image_size=size).mota
    # (undefined where every true box is of such an object)
    return round(share, 4), round(mota, 4) if math.isfinite(mota) else None


def _percept(*args: str) -> str:
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    done = subprocess.run(
        [*PERCEPT, "--log-level", "WARNING", *args],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"percept {' '.join(args)} failed:\n{done.stderr[-2000:]}")
    return done.stdout


@dataclass(frozen=True)
class Run:
    """How every (scene, robot) pair is rendered, tracked and scored."""

    sequences: Path
    """Where the rendered sequences go (one folder per pair)."""
    tracks: Path
    """Where the tracks go (one file per pair): beside the results, not in the sequence, so
    that runs of other parameters sharing the sequences never write one file at once."""
    fps: float
    limit: float
    """Seconds unmatched that make a false anchor persistent."""
    keep: bool
    """Keep the images (a sequence kept whole is not rendered again)."""
    track_args: tuple[str, ...]
    """Perception parameters for percept track (--params, --set)."""


def _rendered(seq: Path) -> bool:
    """Whether ``seq`` holds a whole sequence already (all its ``seqLength`` images)."""
    info = seq / "seqinfo.ini"
    if not info.is_file():
        return False
    length = [
        v
        for k, v in (line.split("=", 1) for line in info.read_text().splitlines() if "=" in line)
        if k == "seqLength"
    ]
    return bool(length) and len(list((seq / "img1").glob("*.png"))) == int(length[0])


def score(scene_file: Path, robot: str, run: Run) -> Result:
    """Render (unless rendered before), track and score one robot's view of one scene."""
    began = time.perf_counter()
    seq = run.sequences / f"{scene_file.stem}-{robot}"
    if not _rendered(seq):
        _percept(
            "sim",
            "--scene",
            str(scene_file),
            "--robot",
            robot,
            "--out",
            str(seq),
            "--fps",
            f"{run.fps:g}",
        )
    tracks = run.tracks / f"{seq.name}.txt"
    scene = load(Scene, scene_file)
    # (the robot's profile as ``percept track --robot`` takes it: a shipped name or a path)
    profile = str(robot_profile(scene.robot(robot)))
    line = _percept("track", str(seq), "--robot", profile, "--out", str(tracks), *run.track_args)
    summary = json.loads(line.strip().splitlines()[-1])
    gt, hyp = read_mot(seq / "gt" / "gt.txt"), read_mot(tracks)
    size = (int(summary["width"]), int(summary["height"]))
    scores = evaluate_tracking(gt, hyp, image_size=size)
    false = false_seconds(gt, hyp, run.fps) if len(hyp) else {}
    share, mota_ignored = floor_like_scores(scene, gt, hyp, size)
    if not run.keep:
        for image in (seq / "img1").glob("*.png"):
            image.unlink()
    return Result(
        scene=scene_file.stem,
        file=str(scene_file),
        robot=robot,
        frames=int(summary["frames"]),
        mota=round(scores.mota, 4),
        idf1=round(scores.idf1, 4),
        # (an anchor judged an agent, a person, is not an object's: percept track leaves it out)
        anchors_per_object=round(
            anchors_per_object(summary["anchors_created"] - summary["agents"], gt), 3
        ),
        persistent_false_anchors=persistent(false, run.limit),
        longest_false_seconds=round(max(false.values(), default=0.0), 2),
        seconds=round(time.perf_counter() - began, 1),
        errors=asdict(error_classes(gt, hyp, size)),
        floor_like_share=share,
        mota_floor_like_ignored=mota_ignored,
    )


def summarise(results: Sequence[Result]) -> dict[str, object]:
    """The distribution over all (scene, robot) pairs, and which targets it meets."""
    mota = np.array([r.mota for r in results])
    apo = np.array([r.anchors_per_object for r in results])
    clean = np.array([r.persistent_false_anchors == 0 for r in results])
    worst = sorted(results, key=lambda r: r.mota)[:3]
    values = {
        "mota_median": round(float(np.median(mota)), 4),
        "mota_p10": round(float(np.percentile(mota, 10)), 4),
        "mota_min": round(float(mota.min()), 4),
        "anchors_per_object_p90": round(float(np.nanpercentile(apo, 90)), 3),
        "share_without_persistent_false": round(float(clean.mean()), 3),
    }
    met = {
        k: (values[k] <= TARGETS[k]) if k == "anchors_per_object_p90" else values[k] >= TARGETS[k]
        for k in TARGETS
    }
    return {
        "pairs": len(results),
        "scenes": len({r.scene for r in results}),
        **values,
        "idf1_median": round(float(np.median([r.idf1 for r in results])), 4),
        "errors": _total_errors(results).shares(),
        "scenes_below_0_80": sorted({r.scene for r in results if r.mota < 0.80}),
        "worst": [
            {"scene": r.scene, "robot": r.robot, "mota": r.mota, "file": r.file} for r in worst
        ],
        "targets": TARGETS,
        "met": met,
        "floor_like": floor_like_summary(results),
    }


def floor_like_summary(results: Sequence[Result]) -> dict[str, object]:
    """How much of the distribution the objects of the floor's colour take: the pairs with one
    in view, the MOTA the rest leave at most (``1 - share``: every such box missed, nothing
    else wrong), and the distribution of MOTA with them ignored."""
    counted = [r for r in results if r.floor_like_share is not None]
    if not counted:
        return {"pairs_counted": 0}
    ceiling = np.array([1.0 - (r.floor_like_share or 0.0) for r in counted])
    ignored = np.array([r.mota_floor_like_ignored for r in counted], float)  # None: NaN
    scored = ignored[np.isfinite(ignored)]
    return {
        "pairs_counted": len(counted),
        "pairs_with_one": int(np.count_nonzero(ceiling < 1.0)),
        "share_of_true_boxes": round(
            float(sum((r.floor_like_share or 0.0) * r.errors.get("boxes", 0) for r in counted))
            / max(1, sum(r.errors.get("boxes", 0) for r in counted)),
            4,
        ),
        "pairs_whose_ceiling_is_below": {
            f"{v:.2f}": int(np.count_nonzero(ceiling < v)) for v in (0.97, 0.90, 0.80)
        },
        "pairs_with_only_those": len(counted) - len(scored),
        "mota_ignored_median": round(float(np.median(scored)), 4),
        "mota_ignored_p10": round(float(np.percentile(scored, 10)), 4),
        "mota_ignored_min": round(float(scored.min()), 4),
    }


def _total_errors(results: Sequence[Result]) -> ErrorClasses:
    """The error classes summed over the pairs that have them."""
    return sum((ErrorClasses.from_counts(r.errors) for r in results if r.errors), NONE)


ERROR_COLUMNS = (
    ("misses", "misses"),
    ("false_boxes", "false boxes"),
    ("merged", "merged"),
    ("too_big", "too big"),
    ("on_a_part", "on a part"),
    ("cut", "cut"),
)


def error_table(results: Sequence[Result]) -> str:
    """Every pair's error classes and their total, as shares of the true boxes."""
    head = "| pair | MOTA | " + " | ".join(label for _, label in ERROR_COLUMNS) + " |"
    lines = [head, "|---" * (len(ERROR_COLUMNS) + 2) + "|"]

    def row(name: str, mota: str, errors: ErrorClasses) -> str:
        shares = errors.shares()
        cells = " | ".join(f"{shares[k]:.3f}" for k, _ in ERROR_COLUMNS)
        return f"| {name} | {mota} | {cells} |"

    counted = [r for r in results if r.errors]
    lines += [
        row(f"{r.scene}-{r.robot}", f"{r.mota:.3f}", ErrorClasses.from_counts(r.errors))
        for r in counted
    ]
    lines.append(row(f"all {len(counted)}", "", _total_errors(counted)))
    return "\n".join(lines)


def figure(results: Sequence[Result], median: float, p10: float) -> np.ndarray:
    """Every pair's MOTA, sorted, as a bar, with the median and the 10th percentile (black, grey)
    and the targets 0.97, 0.90, 0.80 as lines; bars of pairs with a persistent false anchor red,
    and a black tick on a pair with objects of the floor's colour in view at its MOTA with them
    ignored."""
    w, h, margin = 900, 420, 50
    out = np.full((h, w, 3), 255, np.uint8)
    ordered = sorted(results, key=lambda r: r.mota)
    lo = min(0.5, math.floor(10 * ordered[0].mota) / 10 - 0.1)

    def y(v: float) -> int:
        return int(h - margin - (max(v, lo) - lo) / (1.0 - lo) * (h - 2 * margin))

    def text(label: str, at: tuple[int, int], colour: tuple[int, int, int], size: float) -> None:
        cv2.putText(out, label, at, cv2.FONT_HERSHEY_SIMPLEX, size, colour, 1, cv2.LINE_AA)

    step = (w - 2 * margin) / len(ordered)
    for k, r in enumerate(ordered):
        x0 = int(margin + k * step)
        x1 = max(x0, int(margin + (k + 1) * step) - 1)
        colour = (60, 60, 220) if r.persistent_false_anchors else (170, 120, 60)
        cv2.rectangle(out, (x0, y(r.mota)), (x1, y(lo)), colour, -1)
        ignored = r.mota_floor_like_ignored
        if r.floor_like_share and ignored is not None and math.isfinite(ignored):
            cv2.rectangle(out, (x0, y(ignored) - 1), (x1, y(ignored) + 1), (0, 0, 0), -1)
    for v, label, colour in (
        (0.97, "target median 0.97", (0, 150, 0)),
        (0.90, "target p10 0.90", (0, 150, 0)),
        (0.80, "no scene below 0.80", (0, 0, 200)),
    ):
        cv2.line(out, (margin, y(v)), (w - margin, y(v)), colour, 1)
        # (on the left, above the low bars, where the labels cross no bar)
        text(label, (margin + 130, y(v) - 3), colour, 0.4)
    cv2.line(out, (margin, y(median)), (w - margin, y(median)), (0, 0, 0), 1)
    text(f"median {median:.3f}", (margin + 5, y(median) - 3), (0, 0, 0), 0.4)
    cv2.line(out, (margin, y(p10)), (w - margin, y(p10)), (90, 90, 90), 1)
    text(f"p10 {p10:.3f}", (margin + 5, y(p10) + 12), (90, 90, 90), 0.4)
    for v in np.linspace(lo, 1.0, 6):
        text(f"{v:.2f}", (5, y(float(v)) + 4), (0, 0, 0), 0.4)
    title = f"MOTA of {len(ordered)} (scene, robot) pairs, sorted; red: a persistent false anchor"
    text(title, (margin, 20), (0, 0, 0), 0.5)
    note = "black tick: the pair's MOTA with the objects of the floor's colour ignored"
    text(note, (margin, 38), (0, 0, 0), 0.4)
    return out


def table(results: Sequence[Result], summary: dict[str, object]) -> str:
    met = summary["met"]
    assert isinstance(met, dict)
    rows = [
        ("MOTA median", summary["mota_median"], ">= 0.97", met["mota_median"]),
        ("MOTA 10th percentile", summary["mota_p10"], ">= 0.90", met["mota_p10"]),
        ("MOTA lowest", summary["mota_min"], ">= 0.80", met["mota_min"]),
        (
            "anchors per object, 90th percentile",
            summary["anchors_per_object_p90"],
            "<= 1.1",
            met["anchors_per_object_p90"],
        ),
        (
            "pairs without a persistent false anchor",
            summary["share_without_persistent_false"],
            ">= 0.90",
            met["share_without_persistent_false"],
        ),
        ("IDF1 median", summary["idf1_median"], "", None),
    ]
    lines = ["| measure | value | target | met |", "|---|---|---|---|"]
    lines += [
        f"| {a} | {b} | {c} | {'' if d is None else ('yes' if d else 'no')} |"
        for a, b, c, d in rows
    ]
    worst = sorted(results, key=lambda r: r.mota)[:3]
    lines += ["", "worst: " + "; ".join(f"{r.file} robot {r.robot} MOTA {r.mota}" for r in worst)]
    floor = summary["floor_like"]
    assert isinstance(floor, dict)
    if floor["pairs_counted"]:
        below = floor["pairs_whose_ceiling_is_below"]
        lines += [
            "",
            f"objects of the floor's colour (every channel within {FLOOR_LIKE} levels): in view in "
            f"{floor['pairs_with_one']} of {floor['pairs_counted']} pairs, "
            f"{floor['share_of_true_boxes']:.3f} of the true boxes; pairs whose MOTA stays under "
            f"0.97 / 0.90 / 0.80 if every such box is missed: "
            f"{below['0.97']} / {below['0.90']} / {below['0.80']}; MOTA with them ignored: "
            f"median {floor['mota_ignored_median']}, 10th percentile {floor['mota_ignored_p10']}, "
            f"lowest {floor['mota_ignored_min']} (over the {floor['pairs_counted']} pairs less "
            f"{floor['pairs_with_only_those']} that see only such objects)",
        ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--count", type=int, default=60, help="scenes (default 60)")
    p.add_argument("--seed", type=int, default=1, help="seed of the first scene (default 1)")
    p.add_argument("--jobs", type=int, default=2, help="scenes rendered at once (default 2)")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--distribution", help="distribution file (default: the shipped one)")
    p.add_argument("--robots", nargs="+", help="robots to score (default: every robot)")
    p.add_argument("--fps", type=float, default=15.0, help="frames per second (default 15)")
    p.add_argument(
        "--persistent",
        type=float,
        default=10.0,
        help="seconds unmatched that make a false anchor persistent (default 10)",
    )
    p.add_argument("--keep", action="store_true", help="keep the rendered images")
    p.add_argument(
        "--sequences",
        type=Path,
        help="folder of the rendered sequences (default OUT/sequences); with --keep, runs of "
        "other parameters can share it and only track again",
    )
    perception_params.add_arguments(p)  # passed on to percept track as they are
    p.add_argument(
        "--no-markers",
        action="store_true",
        help="percept track --no-markers: the marker boxes are not known objects",
    )
    p.add_argument("--report", action="store_true", help="only aggregate the results there")
    args = p.parse_args(argv)
    out: Path = args.out
    scenes_dir, results_dir = out / "scenes", out / "results"
    results_dir.mkdir(parents=True, exist_ok=True)
    (out / "tracks").mkdir(exist_ok=True)
    if not args.report:
        extra = ["--distribution", args.distribution] if args.distribution else []
        written = json.loads(
            _percept(
                "scenarios",
                "--count",
                str(args.count),
                "--seed",
                str(args.seed),
                "--out",
                str(scenes_dir),
                *extra,
            )
        )
        work = []
        for name in written["scenes"]:
            file = scenes_dir / name
            robots = args.robots or [r.name for r in load(Scene, file).robots]
            for robot in robots:
                done = results_dir / f"{file.stem}-{robot}.json"
                if not done.exists():
                    work.append((file, robot, done))

        track_args = (
            (["--params", args.params] if args.params else [])
            + [a for o in args.overrides for a in ("--set", o)]
            + (["--no-markers"] if args.no_markers else [])
        )
        run = Run(
            args.sequences or out / "sequences",
            out / "tracks",
            args.fps,
            args.persistent,
            args.keep,
            tuple(track_args),
        )

        def one(item: tuple[Path, str, Path]) -> None:
            file, robot, done = item
            try:
                result = score(file, robot, run)
            except RuntimeError as err:
                print(f"{file.stem} {robot}: {err}", file=sys.stderr, flush=True)
                return
            done.write_text(json.dumps(asdict(result)) + "\n", encoding="utf-8")
            print(json.dumps(asdict(result)), flush=True)

        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            list(pool.map(one, work))
    results = [
        Result(**json.loads(f.read_text(encoding="utf-8")))
        for f in sorted(results_dir.glob("*.json"))
    ]
    if not results:
        print("no results yet")
        return 1
    summary = summarise(results)
    report = {
        "command": " ".join(["python", "bench/robustness.py", *(argv or sys.argv[1:])]),
        "measured": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "fps": args.fps,
        "params": args.params,
        "set": args.overrides,
        "persistent_seconds": args.persistent,
        "summary": summary,
        "results": [asdict(r) for r in results],
    }
    (out / "robustness.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    mota = [r.mota for r in results]
    median, p10 = float(np.median(mota)), float(np.percentile(mota, 10))
    cv2.imwrite(str(out / "robustness.png"), figure(results, median, p10))
    print(table(results, summary))
    print()
    print(error_table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
