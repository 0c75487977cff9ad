"""``percept replay``: feed a recording through the daemon's pipeline again (see
:mod:`percept.runtime.record.replay`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

NAME = "replay"
HELP = "replay a recording's frames and joints through the pipeline; compare the world models"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("recording", type=Path, metavar="FILE.mcap", help="made by percept run --record")
    pace = p.add_mutually_exclusive_group()
    pace.add_argument(
        "--speed",
        type=float,
        default=1.0,
        metavar="X",
        help="play at X times the recorded speed (default 1)",
    )
    pace.add_argument(
        "--as-fast-as-possible",
        action="store_true",
        help="no pacing: each frame as soon as the last is done",
    )
    p.add_argument(
        "--robot", type=Path, metavar="TOML", help="platform profile (default: the recorded one)"
    )
    p.add_argument(
        "--experiment", type=Path, metavar="TOML", help="experiment (default: the recorded one)"
    )
    p.add_argument(
        "--out", type=Path, metavar="FILE.jsonl", help="write the world models, one JSON per line"
    )


def run(args: argparse.Namespace) -> int:
    from percept.runtime.record.reader import RecordingError
    from percept.runtime.record.replay import ReplayReport, replay

    if not args.as_fast_as_possible and args.speed <= 0:
        print("percept replay: --speed must be above 0", file=sys.stderr)
        return 2
    if not args.recording.is_file():
        print(f"percept replay: {args.recording}: no such file", file=sys.stderr)
        return 2
    report = ReplayReport()
    worlds = replay(
        args.recording,
        profile_path=args.robot,
        experiment_path=args.experiment,
        speed=None if args.as_fast_as_possible else args.speed,
        report=report,
    )
    try:
        if args.out is None:
            for _ in worlds:
                pass
        else:
            with args.out.open("w", encoding="utf-8") as fh:
                for world in worlds:
                    fh.write(json.dumps(world) + "\n")
    except RecordingError as err:
        print(f"percept replay: {err}", file=sys.stderr)
        return 2
    print(json.dumps(report.summary()))
    if report.note():
        print(f"percept replay: {report.note()}", file=sys.stderr)
    return 0
