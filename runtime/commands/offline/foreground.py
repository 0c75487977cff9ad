"""``percept foreground``: the perception core's foreground mask of every frame, as PNG files.

For pixel-level scoring (``percept eval foreground``): one 0/255 PNG per frame, named after the
input frame (``in000470.jpg`` gives ``in000470.png``; video frames are ``000001.png``...). The
masks are the foreground after noise reduction, before region filtering, as SPEC §4.1 defines it
(``Perception.foreground``; a frame that cannot be decoded gives an empty mask).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from percept.runtime.commands import _sequence
from percept.runtime.commands.offline import _perception_params
from percept.runtime.commands.offline.track import calibrated_perception, frame_step

NAME = "foreground"
HELP = "write the foreground mask of every frame of a sequence as 0/255 PNGs"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", help="video file, image folder or MOTChallenge sequence folder")
    p.add_argument("--out", required=True, type=Path, help="folder for the masks")
    _perception_params.add_calibration_arguments(p)
    _perception_params.add_arguments(p)


def run(args: argparse.Namespace) -> int:
    import cv2
    import numpy as np

    sequence = _sequence.open_sequence(args.source)
    perception = calibrated_perception(args, sequence)
    args.out.mkdir(parents=True, exist_ok=True)
    blank = np.zeros((perception.height, perception.width), np.uint8)
    times: list[float] = []
    for name, _, image in sequence.frames(step=frame_step(perception)):
        start = time.perf_counter()
        mask = perception.foreground(image)  # type: ignore[arg-type]  # None: skipped, logged
        times.append(time.perf_counter() - start)
        mask = blank if mask is None else mask
        cv2.imwrite(str(args.out / f"{name}.png"), mask)
    ms = np.array(times) * 1e3 if times else np.zeros(1)
    print(
        json.dumps(
            {
                "source": str(args.source),
                "out": str(args.out),
                "frames": len(times),
                "ms_per_frame_median": round(float(np.median(ms)), 4),
                "ms_per_frame_p90": round(float(np.percentile(ms, 90)), 4),
            }
        )
    )
    return 0
