"""``percept config``: check a platform profile or an experiment file, or list its keys."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict

from percept.config.loader import fields_doc

NAME = "config"
HELP = "check a robot profile or experiment file and print it as JSON; --explain lists the keys"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", metavar="TOML", help="platform profile to check")
    p.add_argument("--experiment", metavar="TOML", help="experiment file to check")
    p.add_argument(
        "--explain",
        choices=["robot", "experiment"],
        help="list every key of that kind of file with its type, default and meaning",
    )


def run(args: argparse.Namespace) -> int:
    from percept.runtime.settings.experiment import (
        Experiment,
        check_calibration_memory,
        load_experiment,
    )
    from percept.runtime.settings.profile import PlatformProfile, load_profile

    if args.explain:
        cls = PlatformProfile if args.explain == "robot" else Experiment
        for key, kind, default, doc in fields_doc(cls):
            print(f"{key:32} {kind:40} {default:12} {doc}")
        return 0
    if not (args.robot or args.experiment):
        print("percept config: give --robot, --experiment or --explain")
        return 2
    checked = {}
    profile = load_profile(args.robot) if args.robot else None
    if profile is not None:
        checked["robot"] = asdict(profile)
    if args.experiment:
        experiment = load_experiment(args.experiment)
        checked["experiment"] = asdict(experiment)
        if profile is not None:
            camera = profile.camera
            background = experiment.perception.background
            where = "perception.background"
            check_calibration_memory(
                background, camera.width, camera.height, args.experiment, where
            )
    print(json.dumps(checked, indent=2, default=str))
    return 0
