"""Decoding only what perception uses: JPEG frames decoded at full size vs at the grid's scale.

The frames of MOT15 TUD-Stadtmitte and TUD-Campus (640x480, ../shared/data) are encoded as JPEG
(quality 90, as a camera's MJPEG) once; then, in one run:

- decoding: milliseconds per frame of ``cv2.imdecode`` at full size and at half size
  (``IMREAD_REDUCED_COLOR_2``), and of the whole way to perception's YCrCb grid (step 2 at
  640x480): full decode, every 2nd pixel, YCrCb, against half-size decode, YCrCb. The loops
  alternate frame by frame, so a load on the machine falls on both alike.
- quality: MOTA and IDF1 of ``percept track``'s pipeline on the same JPEGs as full frames and as
  grid frames (background calibrated on the same kind of frame as the frames tracked).

    python bench/bench_decode.py [--repeat N]
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
from percept.perception.evaluation.tracking import evaluate_tracking, read_mot  # noqa: E402
from percept.perception.grid_frame import GridFrame, PerceptionFrame  # noqa: E402
from percept.perception.params import PerceptionParams  # noqa: E402
from percept.perception.pipeline import Perception  # noqa: E402
from percept.perception.regions import subsample  # noqa: E402
from percept.runtime.commands._sequence import open_sequence  # noqa: E402
from percept.runtime.commands.track import track_frames  # noqa: E402

DATA = REPO.parent / "shared" / "data" / "mot15-tud"
SEQUENCES = ("TUD-Stadtmitte", "TUD-Campus")


def jpegs(name: str) -> tuple[list[bytes], float]:
    """The frames of a TUD sequence as JPEG bytes, and its frame rate."""
    sequence = open_sequence(DATA / name / f"{name}.mp4")
    encoded = []
    for _, _, image in sequence.frames():
        assert isinstance(image, np.ndarray)
        ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
        assert ok
        encoded.append(data.tobytes())
    return encoded, sequence.fps


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


def quality(name: str, frames: list[bytes], fps: float) -> dict[str, dict[str, float]]:
    """MOTA and IDF1 of the tracking of full frames and of grid frames (as ``eval_quality.py``
    runs TUD: background from all frames of the sequence)."""
    gt = read_mot(DATA / name / "gt" / "gt.txt")
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
        lines, _, skipped = track_frames(perception, ((i / fps, im) for i, im in enumerate(images)))
        assert skipped == 0
        rows = np.array([[float(v) for v in line.split(",")] for line in lines]).reshape(-1, 10)
        scores = evaluate_tracking(gt, rows, image_size=(640, 480)).as_dict()
        out[kind] = {key: scores[key] for key in ("mota", "idf1")}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--repeat", type=int, default=3, help="passes over the frames (timing)")
    args = parser.parse_args()
    all_frames: list[bytes] = []
    for name in SEQUENCES:
        frames, fps = jpegs(name)
        all_frames += frames
        for kind, scores in quality(name, frames, fps).items():
            print(f"{name:15s} {kind:12s} MOTA {scores['mota']:.3f} IDF1 {scores['idf1']:.3f}")
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
