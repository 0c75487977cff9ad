"""Perception quality against ground truth, beside the common alternative; prints one table.

- CDnet 2014 baseline/highway (../shared/data): F1 of percept's foreground (background from the
  469 frames before the scored window, which all have cars in them), also with the chapter
  preset, and of OpenCV MOG2 and KNN, scored the same way (frames 470-1700, 255 positive, 0 and
  50 negative, 85 and 170 ignored).
- MOT15 TUD-Campus and TUD-Stadtmitte: MOTA, IDF1, ID switches, FP, FN of percept with and
  without colour splitting, and of MOG2 + a Kalman blob tracker (background from all frames of
  the sequence for percept; MOG2 learns on them first).
- The simulated busy table-top scene (``percept sim --scene tabletop-busy``, 30 s, robot a; the
  first 2 s are empty and calibrate the background) and the synthetic busy scene of
  ``bench_perception.py`` at 176x144 and 640x480.

    python bench/eval_quality.py [--only cdnet tud sim synthetic] [--set KEY=VALUE ...]

``--set`` changes percept's parameters for every run (as for ``percept track``). Each row can be
reproduced with the ``percept`` commands printed under the table.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.baseline import Mog2Tracker  # noqa: E402
from percept.perception.evaluation.foreground import frame_counts, pooled, read_temporal_roi  # noqa: E402
from percept.perception.evaluation.synthetic import busy_scene  # noqa: E402
from percept.perception.evaluation.tracking import evaluate_tracking, mot_box, read_mot  # noqa: E402
from percept.perception.params import PerceptionParams  # noqa: E402
from percept.perception.pipeline import Perception  # noqa: E402
from percept.runtime.commands._sequence import open_sequence  # noqa: E402
from percept.runtime.commands.offline import _perception_params  # noqa: E402
from percept.runtime.commands.offline.track import track_frames  # noqa: E402

DATA = REPO.parent / "shared" / "data"
CHAPTER = REPO / "config" / "presets" / "perception-chapter.toml"


def _params(base: PerceptionParams, **changes) -> PerceptionParams:
    out = base
    for table, values in changes.items():
        out = replace(out, **{table: replace(getattr(out, table), **values)})
    return out


def variants(base: PerceptionParams, chapter: bool) -> dict[str, tuple[PerceptionParams, str]]:
    """percept's configurations to compare, with their ``percept track`` options.

    The chapter preset (k = 1: a large share of the pixels of a camera image are foreground,
    and every speck can seed a model) takes from a third of a second to seconds per frame when
    tracking, so it is run only where asked (the CDnet foreground).
    """
    from percept.config.loader import load

    out = {
        "percept": (base, ""),
        "percept, no split": (
            _params(base, split={"enabled": False}),
            " --set split.enabled=false",
        ),
    }
    if chapter:
        out["percept, chapter preset"] = (load(PerceptionParams, CHAPTER), " --params chapter")
    return out


def _mot_rows(rows: list[tuple]) -> np.ndarray:
    """MOT rows from (frame, id, left, top, width, height) tuples of image boxes."""
    table = [[frame, number, *mot_box(box), 1, -1, -1, -1] for frame, number, *box in rows]
    return np.array(table, float).reshape(-1, 10)


def _parse(lines: list[str]) -> np.ndarray:
    """MOT rows from the text lines ``percept track`` writes."""
    return np.array([[float(v) for v in line.split(",")] for line in lines]).reshape(-1, 10)


def _alternative_rows(frames: list[np.ndarray], learn: list[np.ndarray]) -> np.ndarray:
    h, w = frames[0].shape[:2]
    alternative = Mog2Tracker(w, h)
    alternative.learn(learn)
    rows = []
    for index, image in enumerate(frames, start=1):
        rows += [(index, *track) for track in alternative.process(image)]
    return _mot_rows(rows)


def _calibrating_on(params: PerceptionParams, frames: int) -> PerceptionParams:
    """``params`` with ``calibration_frames`` set as ``--calibration-frames`` sets it."""
    return _params(params, background={"calibration_frames": frames})


def _percept_rows(params: PerceptionParams, frames: list[np.ndarray], calib: int, fps: float):
    h, w = frames[0].shape[:2]
    perception = Perception(_calibrating_on(params, calib), w, h)
    perception.calibrate(frames[:calib])
    tracks = track_frames(perception, ((i / fps, im) for i, im in enumerate(frames)))
    return _parse(tracks.rows), float(np.median(tracks.times) * 1e3)


def tracking_rows(
    name: str,
    frames: list[np.ndarray],
    gt: np.ndarray,
    calibration: int,
    fps: float,
    base: PerceptionParams,
    command: str,
    chapter: bool = False,
) -> Iterator[dict]:
    size = (frames[0].shape[1], frames[0].shape[0])
    for label, (params, options) in variants(base, chapter).items():
        rows, ms = _percept_rows(params, frames, calibration, fps)
        yield {
            "data": name,
            "method": label,
            "ms": ms,
            **evaluate_tracking(gt, rows, image_size=size).as_dict(),
            "command": f"{command} --calibration-frames {calibration}{options}",
        }
    rows = _alternative_rows(frames, frames[:calibration])
    yield {
        "data": name,
        "method": "MOG2 + Kalman",
        **evaluate_tracking(gt, rows, image_size=size).as_dict(),
    }


def _read(source: Path) -> tuple[list[np.ndarray], float]:
    sequence = open_sequence(source)
    return [im for _, _, im in sequence.frames()], sequence.fps


def tud(base: PerceptionParams) -> Iterator[dict]:
    for name in ("TUD-Campus", "TUD-Stadtmitte"):
        folder = DATA / "mot15-tud" / name
        frames, fps = _read(folder / f"{name}.mp4")
        gt = read_mot(folder / "gt" / "gt.txt")
        command = f"percept track {folder}/{name}.mp4 --out {name}.txt"
        yield from tracking_rows(name, frames, gt, len(frames), fps, base, command)


def sim(base: PerceptionParams) -> Iterator[dict]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "busy"
        command = ["percept", "sim", "--scene", "tabletop-busy", "--robot", "a", "--out", str(out)]
        done = subprocess.run(
            [sys.executable, "-m", "percept.runtime.cli", *command[1:]],
            cwd=REPO,
            capture_output=True,
            encoding="utf-8",
        )
        if done.returncode != 0:
            yield {"data": "sim tabletop-busy", "method": "not available: " + done.stderr[-200:]}
            return
        frames, fps = _read(out)
        gt = read_mot(out / "gt" / "gt.txt")
        track = "percept sim --scene tabletop-busy --robot a --out busy && percept track busy"
        track += " --out busy.txt"
        yield from tracking_rows(
            "sim tabletop-busy (a)", frames, gt, int(2 * fps), fps, base, track
        )


def synthetic(base: PerceptionParams) -> Iterator[dict]:
    for w, h in ((176, 144), (640, 480)):
        scene = busy_scene(w, h, 300)
        frames = scene.empty(30) + [scene.render(i) for i in range(300)]
        lines = [
            (f + 31, i, x, y, bw, bh) for f in range(300) for i, x, y, bw, bh in scene.truth(f)
        ]
        gt = _mot_rows(lines)
        name = f"synthetic {w}x{h}"
        command = "python bench/eval_quality.py --only synthetic (in-process)"
        yield from tracking_rows(name, frames, gt, 30, 25.0, base, command)


CDNET = DATA / "cdnet2014-highway"


def cdnet_data() -> tuple[list[np.ndarray], int, Callable[[list[np.ndarray]], dict]]:
    """CDnet highway: frames 1..last, the first scored frame, and the score of the masks of
    frames first..last (CDnet's protocol, inside the ROI)."""
    folder = CDNET
    first, last = read_temporal_roi(folder / "temporalROI.txt")
    frames = [cv2.imread(str(folder / "input" / f"in{i:06d}.jpg")) for i in range(1, last + 1)]
    gts = [
        cv2.imread(str(folder / "groundtruth" / f"gt{i:06d}.png"), cv2.IMREAD_GRAYSCALE)
        for i in range(first, last + 1)
    ]
    roi = cv2.imread(str(folder / "ROI.bmp"), cv2.IMREAD_GRAYSCALE)

    def score(masks: list[np.ndarray]) -> dict:
        return pooled(frame_counts(g, m, roi) for g, m in zip(gts, masks, strict=True)).as_dict()

    return frames, first, score


def cdnet(base: PerceptionParams) -> Iterator[dict]:
    folder = CDNET
    frames, first, score = cdnet_data()
    h, w = frames[0].shape[:2]

    command = (
        f"percept foreground {folder}/input --calibration-frames {first - 1} --out masks{{}}"
        f" && percept eval foreground --gt {folder}/groundtruth --masks masks"
    )
    for label, (params, options) in variants(base, chapter=True).items():
        if "no split" in label:
            continue  # the split does not change the foreground
        perception = Perception(_calibrating_on(params, first - 1), w, h)
        perception.calibrate(frames[: first - 1])
        masks = [perception.foreground(image) for image in frames[first - 1 :]]
        yield {
            "data": "CDnet highway",
            "method": label,
            **score(masks),
            "command": command.format(options),
        }
    kernel = np.ones((3, 3), np.uint8)
    for name, make in (
        ("MOG2", cv2.createBackgroundSubtractorMOG2),
        ("KNN", cv2.createBackgroundSubtractorKNN),
    ):
        for opened in (False, True):
            subtractor = make()
            masks = []
            for i, image in enumerate(frames):
                mask = cv2.threshold(subtractor.apply(image), 200, 255, cv2.THRESH_BINARY)[1]
                if opened:
                    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
                if i + 1 >= first:
                    masks.append(mask)
            label = f"{name}{' + 3x3 opening' if opened else ''} (OpenCV defaults)"
            yield {"data": "CDnet highway", "method": label, **score(masks)}


def _table(rows: list[dict]) -> None:
    print(
        f"{'data':24} {'method':30} {'MOTA':>7} {'IDF1':>6} {'IDSW':>5} {'FP':>6} {'FN':>6}"
        f" {'ms':>6} | {'P':>6} {'R':>6} {'F1':>6}"
    )
    for r in rows:
        if "mota" in r:
            ms = f"{r['ms']:6.2f}" if "ms" in r else " " * 6
            print(
                f"{r['data']:24} {r['method']:30} {r['mota']:7.3f} {r['idf1']:6.3f} "
                f"{r['id_switches']:5d} {r['fp']:6d} {r['fn']:6d} {ms} |"
            )
        elif "f1" in r:
            print(
                f"{r['data']:24} {r['method']:30} {'':7} {'':6} {'':5} {'':6} {'':6} {'':6} | "
                f"{r['precision']:6.3f} {r['recall']:6.3f} {r['f1']:6.3f}"
            )
        else:
            print(f"{r['data']:24} {r['method']}")
    print()
    for r in rows:
        if "command" in r:
            print(f"# {r['data']}, {r['method']}:\n{r['command']}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only",
        nargs="+",
        choices=["cdnet", "tud", "sim", "synthetic"],
        default=["cdnet", "tud", "sim", "synthetic"],
    )
    _perception_params.add_arguments(parser)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    base = _perception_params.params_from_args(args)
    runs = {"cdnet": cdnet, "tud": tud, "sim": sim, "synthetic": synthetic}
    rows = []
    for name in args.only:
        for row in runs[name](base):
            rows.append(row)
            print(".", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    _table(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
