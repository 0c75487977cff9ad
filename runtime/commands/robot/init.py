"""``percept init``: copy the shipped configuration into a folder a user edits.

The installed package carries the robot profiles, experiments, scenes, perception presets,
feature statistics and the lab router's file (:mod:`percept.config`); ``percept init DIR`` writes
them to ``DIR/robots/``, ``DIR/experiments/``, ... with the same relative paths between them, so
``percept run --experiment DIR/experiments/tabletop.toml`` uses the copied profiles. A file that
is already there is kept, never overwritten.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

NAME = "init"
HELP = "copy the shipped robot profiles, experiments, scenes and presets into a folder to edit"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dir", type=Path, metavar="DIR", help="the folder (made if missing)")


def run(args: argparse.Namespace) -> int:
    from percept.config import KINDS, shipped_dir

    source = shipped_dir()
    if args.dir.exists() and not args.dir.is_dir():
        print(f"percept init: {args.dir} is not a folder", file=sys.stderr)
        return 2
    written, kept = 0, 0
    for kind in KINDS:
        for path in sorted((source / kind).glob("*.toml")):
            target = args.dir / kind / path.name
            if target.exists():
                kept += 1
                print(f"kept {target} (already there)")
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, target)
            written += 1
    print(
        f"percept init: {written} files written to {args.dir}" + (f", {kept} kept" if kept else "")
    )
    return 0
