"""``percept demo``: the main job, two simulated robots end to end (see
:mod:`percept.runtime.demo`)."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "demo"
HELP = "two simulated robots, their daemons, joint attention and pointing; a summary and figure"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", default="tabletop-basic", help="scene name or file")
    p.add_argument("--seconds", type=float, default=30.0, metavar="T", help="how long (default 30)")
    p.add_argument(
        "--out", type=Path, default=Path("out/demo"), metavar="DIR", help="output folder"
    )
    p.add_argument(
        "--experiment",
        default="tabletop",
        metavar="TOML|NAME",
        help="experiment file or shipped name (default: tabletop)",
    )
    p.add_argument(
        "--gaze",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="the daemons move the simulated heads themselves (percept run --enable-gaze): the "
        "calibration sweep and the looks of the pointing games, instead of the scene's head "
        "keyframes (default: on for scenes whose heads move, e.g. tabletop-look)",
    )


def run(args: argparse.Namespace) -> int:
    from percept.drivers.sim import require_mujoco
    from percept.runtime.demo import DemoOptions, run_demo
    from percept.runtime.settings.scene import find_scene

    if args.seconds <= 0:
        print("percept demo: --seconds must be above 0")
        return 2
    require_mujoco()
    options = DemoOptions(
        scene=find_scene(args.scene),
        seconds=args.seconds,
        out=args.out,
        experiment=args.experiment,
        log_level=args.log_level,
        gaze=args.gaze,
    )
    return run_demo(options)
