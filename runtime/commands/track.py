"""``percept track``: run the perception core over a recorded sequence, write MOTChallenge tracks.

The background is learned from the sequence's first N frames (robust statistics, so people or
objects passing then are tolerated) or loaded with ``--background``. Every frame is then
processed in order; each anchor that a percept was associated with in a frame gives one row
``frame,id,left,top,width,height,conf,-1,-1,-1`` (frames from 1, the anchor's number as id,
conf 1). One JSON line on stdout sums up, with the time of perception alone per frame (decoding
and writing excluded).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from percept.runtime.commands import _perception_params, _sequence

NAME = "track"
HELP = "track objects in a video, image folder or MOTChallenge sequence; write MOT tracks"

log = logging.getLogger("percept.track")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", help="video file, image folder or MOTChallenge sequence folder")
    p.add_argument("--out", required=True, type=Path, help="tracks file to write (MOT format)")
    _perception_params.add_calibration_arguments(p)
    p.add_argument("--save-background", type=Path, metavar="NPZ", help="save the calibration")
    _perception_params.add_arguments(p)


def progress_printer(label: str) -> Callable[[int, int], None]:
    """A ``progress(done, total)`` callback that keeps one line on stderr up to date."""
    tty = sys.stderr.isatty()

    def show(done: int, total: int) -> None:
        if tty:
            end = "\n" if done >= total else ""
            print(f"\r{label}: {done}/{total}", end=end, file=sys.stderr, flush=True)
        elif done == total or done % max(1, total // 4) == 0:
            log.info("%s: %d/%d frames", label, done, total)

    return show


def calibrated_perception(args: argparse.Namespace, sequence: _sequence.Sequence):
    """A :class:`~percept.perception.pipeline.Perception` for ``sequence`` with its background
    ready."""
    from percept.perception.pipeline import Perception
    from percept.runtime.settings.experiment import check_calibration_memory

    params = _perception_params.params_from_args(args)
    if args.calibration_frames is not None:
        if args.calibration_frames < 1:
            raise SystemExit("percept: --calibration-frames must be at least 1")
        background = replace(params.background, calibration_frames=args.calibration_frames)
        params = replace(params, background=background)
    width, height = sequence.size()
    perception = Perception(params, width, height)
    if getattr(args, "background", None):
        perception.load_background(args.background)
    else:
        given = "--calibration-frames" if args.calibration_frames is not None else None
        source = given or args.params or "(default parameters)"
        check_calibration_memory(params.background, width, height, source, "background")
        n = params.background.calibration_frames
        frames = (image for _, _, image in sequence.frames(limit=n) if image is not None)
        perception.calibrate(frames, progress_printer("calibrating"))
    if getattr(args, "save_background", None):
        perception.save_background(args.save_background)
    return perception


def track_frames(perception, frames) -> tuple[list[str], list[float], int]:
    """MOT rows of the visible anchors, perception seconds per frame, and frames skipped.

    ``frames`` yields ``(t, image)``; frame numbers in the rows count from 1.
    """
    rows: list[str] = []
    times: list[float] = []
    skipped = 0
    for index, (t, image) in enumerate(frames, start=1):
        start = time.perf_counter()
        result = perception.process(image, t)
        times.append(time.perf_counter() - start)
        skipped += result.skipped
        for a in result.anchors:
            if a.visible and not result.skipped:
                left, top, w, h = a.bbox
                rows.append(f"{index},{a.number},{left:.2f},{top:.2f},{w:.2f},{h:.2f},1,-1,-1,-1")
    return rows, times, skipped


def run(args: argparse.Namespace) -> int:
    import numpy as np

    sequence = _sequence.open_sequence(args.source)
    perception = calibrated_perception(args, sequence)
    rows, times, skipped = track_frames(perception, ((t, im) for _, t, im in sequence.frames()))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("".join(r + "\n" for r in rows))
    ms = np.array(times) * 1e3 if times else np.zeros(1)
    summary = {
        "source": str(args.source),
        "out": str(args.out),
        "frames": len(times),
        "skipped_frames": skipped,
        "width": perception.width,
        "height": perception.height,
        "rows": len(rows),
        "anchors_created": perception.tracker.created_count,
        "ms_per_frame_median": round(float(np.median(ms)), 4),
        "ms_per_frame_p90": round(float(np.percentile(ms, 90)), 4),
        "ms_per_frame_mean": round(float(np.mean(ms)), 4),
    }
    print(json.dumps(summary))
    return 0
