"""``percept eval``: score tracks (MOTA, IDF1) or foreground masks (CDnet F1); prints JSON.

``percept eval tracking --gt gt.txt --tracks tracks.txt`` reads MOTChallenge files; the image
size for clipping ground-truth boxes comes from ``seqinfo.ini`` beside ``gt/`` when there is one.
``percept eval foreground --gt DIR --masks DIR`` pairs ground-truth and mask images by the last
number in their names; ``ROI.bmp`` and ``temporalROI.txt`` beside the ground-truth folder are
used unless ``--roi`` / ``--temporal-roi`` say otherwise.
"""

from __future__ import annotations

import argparse
import configparser
import json
import sys
from collections.abc import Iterator
from pathlib import Path

from percept.config.loader import ConfigError

NAME = "eval"
HELP = "score tracks against MOT ground truth or foreground masks against CDnet ground truth"


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="what", metavar="WHAT", required=True)
    t = sub.add_parser("tracking", help="MOTA, IDF1, ID switches, FP, FN of MOT tracks")
    t.add_argument("--gt", required=True, type=Path, help="MOTChallenge gt.txt")
    t.add_argument("--tracks", required=True, type=Path, help="MOTChallenge tracks file")
    t.add_argument("--iou", type=float, default=0.5, help="IoU for a match (default 0.5)")
    t.add_argument(
        "--size",
        metavar="WxH",
        help="image size for clipping ground truth (default: from seqinfo.ini, else no clipping)",
    )
    f = sub.add_parser("foreground", help="CDnet precision, recall and F1 of foreground masks")
    f.add_argument("--gt", required=True, type=Path, help="folder of CDnet ground-truth PNGs")
    f.add_argument("--masks", required=True, type=Path, help="folder of 0/255 mask images")
    f.add_argument("--roi", type=Path, help="spatial ROI image (default: ../ROI.bmp if present)")
    f.add_argument(
        "--temporal-roi",
        type=Path,
        help="first and last scored frame (default: ../temporalROI.txt if present, else all)",
    )


def _seqinfo_size(gt: Path) -> tuple[int, int] | None:
    for folder in (gt.parent, gt.parent.parent):
        ini = folder / "seqinfo.ini"
        if ini.is_file():
            parser = configparser.ConfigParser()
            parser.read(ini)
            w = parser.getint("Sequence", "imWidth", fallback=0)
            h = parser.getint("Sequence", "imHeight", fallback=0)
            if w and h:
                return w, h
    return None


def _tracking(args: argparse.Namespace) -> dict[str, object]:
    from percept.perception.evaluation.tracking import evaluate_tracking, read_mot

    for path in (args.gt, args.tracks):
        if not path.is_file():
            raise ConfigError(path, "", "file not found")
    if args.size:
        try:
            w, h = (int(v) for v in args.size.lower().split("x"))
        except ValueError:
            raise ConfigError("--size", args.size, "expected WxH, e.g. 640x480") from None
        size: tuple[int, int] | None = (w, h)
    else:
        size = _seqinfo_size(args.gt)
    scores = evaluate_tracking(read_mot(args.gt), read_mot(args.tracks), args.iou, size)
    return {"gt": str(args.gt), "tracks": str(args.tracks), "iou": args.iou, "clip_to": size} | (
        scores.as_dict()
    )


def _foreground(args: argparse.Namespace) -> dict[str, object]:
    import cv2

    from percept.drivers.camera.image_file import ImageFileError, read_image
    from percept.perception.evaluation.foreground import (
        frame_counts,
        frame_number,
        pooled,
        read_temporal_roi,
    )

    if not args.gt.is_dir() or not args.masks.is_dir():
        raise ConfigError(args.gt if not args.gt.is_dir() else args.masks, "", "not a folder")
    roi_path = args.roi or (args.gt.parent / "ROI.bmp")
    roi = None
    if roi_path.is_file() or args.roi:
        try:
            roi = read_image(roi_path, cv2.IMREAD_GRAYSCALE)
        except ImageFileError as err:
            raise ConfigError("--roi", "", str(err)) from None
    window_path = args.temporal_roi or (args.gt.parent / "temporalROI.txt")
    window = read_temporal_roi(window_path) if window_path.is_file() else None
    masks = {frame_number(p): p for p in args.masks.iterdir() if p.suffix.lower() == ".png"}
    skipped: list[dict[str, str]] = []

    def counts() -> Iterator[tuple[int, int, int, int]]:
        for path in sorted(args.gt.iterdir()):
            n = frame_number(path)
            if n is None or path.suffix.lower() not in (".png", ".bmp"):
                continue
            if window is not None and not window[0] <= n <= window[1]:
                continue
            if n not in masks:
                raise ConfigError(args.masks, "", f"no mask for ground-truth frame {n}")
            try:
                gt = read_image(path, cv2.IMREAD_GRAYSCALE)
                mask = read_image(masks[n], cv2.IMREAD_GRAYSCALE)
                counted = frame_counts(gt, mask, roi)
            except (ImageFileError, ValueError) as err:  # reported, and the other frames count
                print(f"percept eval: frame {n} skipped: {err}", file=sys.stderr)
                skipped.append({"frame": str(n), "error": str(err)})
                continue
            yield counted

    scores = pooled(counts())
    return (
        {
            "gt": str(args.gt),
            "masks": str(args.masks),
            "roi": str(roi_path) if roi is not None else None,
            "temporal_roi": list(window) if window else None,
        }
        | scores.as_dict()
        | {"skipped": skipped}
    )


def run(args: argparse.Namespace) -> int:
    result = _tracking(args) if args.what == "tracking" else _foreground(args)
    print(json.dumps(result, allow_nan=False))
    return 1 if result.get("skipped") else 0
