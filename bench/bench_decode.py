"""Decoding only what perception uses: JPEG frames decoded at full size vs at the grid's scale.

The frames of MOT15 TUD-Stadtmitte and TUD-Campus (640x480, ../shared/data) are encoded as JPEG
(quality 90, as a camera's MJPEG) once; then, in one run:

- decoding: milliseconds per frame of ``cv2.imdecode`` at full size and at half size
  (``IMREAD_REDUCED_COLOR_2``), and of the whole way to perception's YCrCb grid (step 2 at
  640x480): full decode, every 2nd pixel, YCrCb, against half-size decode, YCrCb. The loops
  alternate frame by frame, so a load on the machine falls on both alike.
- quality: MOTA and IDF1 of ``percept track``'s pipeline on the same JPEGs as full frames and as
  grid frames (background calibrated on the same kind of frame as the frames tracked): the two
  TUD sequences (pedestrians: not a scene percept is made for, MOTA below 0 either way) and the
  synthetic busy scene of ``bench_perception.py`` at 640x480 (30 empty frames, then 300).

    python bench/bench_decode.py [--repeat N] [--timing-only] [--sequence DIR ...]

``--sequence`` adds the tracking rows of a 640x480 ``percept sim`` folder (its PNG frames
encoded as JPEG the same way; ``seqinfo.ini`` says how many frames calibrate), e.g. of
``percept sim --scene tabletop-myon --robot a --out myon``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from percept.drivers.camera.decode import decode_jpeg  # noqa: E402
from percept.perception.colour import to_ycrcb  # noqa: E402
from percept.perception.evaluation.synthetic import busy_scene  # noqa: E402
from percept.perception.evaluation.tracking import (  # noqa: E402
    evaluate_tracking,
    mot_box,
    read_mot,
)
from percept.perception.params import PerceptionParams  # noqa: E402
from percept.perception.pipeline import Perception  # noqa: E402
from percept.perception.segmentation.grid_frame import GridFrame, PerceptionFrame  # noqa: E402
from percept.perception.segmentation.labelling.regions import subsample  # noqa: E402
from percept.runtime.commands._sequence import open_sequence  # noqa: E402
from percept.runtime.commands.offline.track import track_frames  # noqa: E402

DATA = REPO.parent / "shared" / "data" / "mot15-tud"
SEQUENCES = ("TUD-Stadtmitte", "TUD-Campus")


def jpegs(name: str) -> tuple[list[bytes], float]:
    """The frames of a TUD sequence as JPEG bytes, and its frame rate."""
    sequence = open_sequence(DATA / name / f"{name}.mp4")
    encoded = []
    for _, _, image in sequence.frames():
        assert isinstance(image, np.ndarray)
        encoded.append(_encoded(image))
    return encoded, sequence.fps


def _encoded(image: np.ndarray) -> bytes:
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return data.tobytes()


def synthetic() -> tuple[list[bytes], np.ndarray]:
    """The synthetic busy scene at 640x480 as JPEG bytes (30 empty frames, then 300), and its
    ground truth as MOT rows (frames from 1)."""
    scene = busy_scene(640, 480, 300)
    images = scene.empty(30) + [scene.render(i) for i in range(300)]
    truth = [
        [f + 31, i, *mot_box((x, y, w, h)), 1, -1, -1, -1]
        for f in range(300)
        for i, x, y, w, h in scene.truth(f)
    ]
    return [_encoded(image) for image in images], np.array(truth, float).reshape(-1, 10)


def _decoded(data: bytes, step: int) -> np.ndarray:
    image = decode_jpeg(data, step)
    assert image is not None
    return image


def timing(frames: list[bytes], repeat: int) -> dict[str, float]:
    """Median milliseconds per frame of each way, alternating frame by frame."""
    ways = {
        "decode full": lambda d: _decoded(d, 1),
        "decode half": lambda d: _decoded(d, 2),
        "to grid YCrCb, full decode": lambda d: to_ycrcb(subsample(_decoded(d, 1), 2)),
        "to grid YCrCb, half decode": lambda d: to_ycrcb(_decoded(d, 2)),
    }
    times: dict[str, list[float]] = {name: [] for name in ways}
    for _ in range(repeat):
        for data in frames:
            for name, way in ways.items():
                start = time.perf_counter()
                way(data)
                times[name].append(time.perf_counter() - start)
    return {name: statistics.median(t) * 1e3 for name, t in times.items()}


def quality(
    frames: list[bytes], gt: np.ndarray, calibration: int, fps: float
) -> dict[str, dict[str, float]]:
    """MOTA and IDF1 of the tracking of full frames and of grid frames, the background from the
    first ``calibration`` frames (as ``eval_quality.py`` runs them)."""
    out = {}
    kinds: dict[str, list[PerceptionFrame]] = {
        "full frames": [_decoded(d, 1) for d in frames],
        "grid frames": [GridFrame.of(_decoded(d, 2), 2) for d in frames],
    }
    for kind, images in kinds.items():
        params = PerceptionParams()
        params = replace(
            params, background=replace(params.background, calibration_frames=len(images))
        )
        perception = Perception(params, 640, 480)
        perception.calibrate(images)
        tracks = track_frames(perception, ((i / fps, im) for i, im in enumerate(images)))
        assert tracks.skipped == 0
        rows = np.array([[float(v) for v in line.split(",")] for line in tracks.rows])
        rows = rows.reshape(-1, 10)
        scores = evaluate_tracking(gt, rows, image_size=(640, 480)).as_dict()
        out[kind] = {key: scores[key] for key in ("mota", "idf1")}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--repeat", type=int, default=3, help="passes over the frames (timing)")
    parser.add_argument("--timing-only", action="store_true", help="leave out the tracking")
    parser.add_argument(
        "--sequence", nargs="*", default=[], type=Path, help="percept sim folders at 640x480"
    )
    args = parser.parse_args()
    all_frames: list[bytes] = []
    rows: list[tuple[str, list[bytes], np.ndarray, int, float]] = []
    for name in SEQUENCES:
        frames, fps = jpegs(name)
        all_frames += frames
        rows.append((name, frames, read_mot(DATA / name / "gt" / "gt.txt"), len(frames), fps))
    if not args.timing_only:
        rows.append(("synthetic busy", *synthetic(), 30, 25.0))
        for folder in args.sequence:
            sequence = open_sequence(folder)
            images = [im for _, _, im in sequence.frames() if isinstance(im, np.ndarray)]
            gt = read_mot(folder / "gt" / "gt.txt")
            calibration = sequence.calibration_frames or 30
            rows.append(
                (folder.name, [_encoded(im) for im in images], gt, calibration, sequence.fps)
            )
        for name, frames, gt, calibration, fps in rows:
            for kind, scores in quality(frames, gt, calibration, fps).items():
                mota, idf1 = scores["mota"], scores["idf1"]
                print(f"{name:15s} {kind:12s} MOTA {mota:.3f} IDF1 {idf1:.3f}")
    ms = timing(all_frames, args.repeat)
    print(f"{len(all_frames)} JPEG frames of 640x480, {args.repeat} passes, ms per frame (median):")
    for name, value in ms.items():
        print(f"  {name:28s} {value:.3f}")
    print(f"  decode full / half: {ms['decode full'] / ms['decode half']:.2f}x")
    ratio = ms["to grid YCrCb, full decode"] / ms["to grid YCrCb, half decode"]
    print(f"  to grid YCrCb full / half: {ratio:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
