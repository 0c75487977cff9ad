"""``percept scenes``: the scene data set of language games (see
:mod:`percept.runtime.games.language.dataset.joint_scenes`).

Writes ``DIR/scenes.jsonl`` (one joint-attention scene a line,
:mod:`percept.runtime.games.language.dataset.records`), ``DIR/scaling.toml`` (the experiment's
feature statistics the scaled values were made with), ``DIR/agreement.json`` (per feature ``d``,
``r``, ``n``: :mod:`percept.runtime.games.language.dataset.agreement`) and
``DIR/agreement.png``, and ``DIR/agreement_truth.json``, the same for the true features (how much
the objects themselves look different from the two sides); prints one JSON line. Scenes are
written as they are made.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from percept.perception.features.scaling import FeatureScaling
    from percept.runtime.games.language.dataset.joint_scenes import SceneCapture
    from percept.runtime.settings.experiment import Experiment

NAME = "scenes"
HELP = "random table-top scenes seen by both simulated robots' pipelines: a language-game data set"


log = logging.getLogger("percept.scenes")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--count", type=int, required=True, metavar="N", help="scenes to make")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument(
        "--experiment",
        default="tabletop",
        metavar="E",
        help="experiment file or shipped name: robots, perception, boxes, scaling (default: "
        "tabletop)",
    )


def run(args: argparse.Namespace) -> int:
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    from percept.config.loader import ConfigError
    from percept.perception.features.scaling import FeatureScaling
    from percept.runtime.settings.experiment import load_experiment

    if args.count < 1 or args.seed < 0:
        print("percept scenes: --count must be at least 1 and --seed not negative")
        return 2
    experiment = load_experiment(args.experiment)
    if len(experiment.robots) != 2:
        raise ConfigError(args.experiment, "robots", "scenes need an experiment of two robots")
    capture = _scene_capture(args, experiment)
    args.out.mkdir(parents=True, exist_ok=True)
    scaling = FeatureScaling.from_settings(experiment.scaling)
    scaling.save(args.out / "scaling.toml", f"Feature statistics of {args.experiment}.")
    began, cpu = time.perf_counter(), time.process_time()
    path = _capture(args, capture, began)
    seconds, cpu = time.perf_counter() - began, time.process_time() - cpu
    table = _agreement(args.out, path, scaling)
    print(
        json.dumps(
            {
                "out": str(args.out),
                "scenes": args.count,
                "seconds": round(seconds, 1),
                "scenes_per_second": round(args.count / seconds, 2),
                "cpu_seconds": round(cpu, 1),
                "scenes_per_cpu_second": round(args.count / cpu, 2),
                "agreement": table,
            }
        )
    )
    return 0


def _scene_capture(args: argparse.Namespace, experiment: Experiment) -> SceneCapture:
    """The two robots' scene capture; the experiment's boxes must be the table-top ones."""
    from percept.config.loader import ConfigError
    from percept.runtime.games.language.dataset.joint_scenes import (
        CaptureSettings,
        SceneCapture,
        boxes_match,
    )
    from percept.runtime.settings.profile import load_profile

    a, b = experiment.robots
    platforms = {r.name: load_profile(r.profile) for r in experiment.robots}
    settings = CaptureSettings(names=(a.name, b.name), profiles=(a.profile, b.profile))
    capture = SceneCapture(experiment, platforms, settings)
    if not boxes_match(experiment.landmarks):
        raise ConfigError(
            args.experiment, "landmarks.boxes", "boxes 1 and 2 with markers 0-7 as in tabletop.toml"
        )
    return capture


def _capture(args: argparse.Namespace, capture: SceneCapture, began: float) -> Path:
    """Make the scenes into ``scenes.jsonl``, each written as it is made; returns its path."""
    from percept.runtime.games.language.dataset.joint_scenes import capture_scenes
    from percept.runtime.games.language.dataset.records import dumps

    def progress(done: int, total: int) -> None:
        rate = done / (time.perf_counter() - began)
        if done == total or done % max(1, total // 20) == 0:
            log.info("scene %d/%d (%.2f scenes/s)", done, total, rate)

    path = args.out / "scenes.jsonl"
    with path.open("w", encoding="utf-8") as fh:
        for record in capture_scenes(capture, args.count, args.seed, progress):
            fh.write(dumps(record) + "\n")
            fh.flush()
    return path


def _agreement(
    out: Path, path: Path, scaling: FeatureScaling
) -> dict[str, dict[str, float | int | None]]:
    """Write the perceived and the true features' agreement (``agreement.json`` and ``.png``,
    ``agreement_truth.json``); returns the perceived one's table."""
    import cv2

    from percept.runtime.games.language.dataset.agreement import agreement, feature_pairs
    from percept.runtime.games.language.dataset.records import read_scenes
    from percept.runtime.games.language.figures import agreement_figure

    scenes = list(read_scenes(path))
    results = agreement(feature_pairs(scenes, scaling))
    table = {f: r.to_json() for f, r in results.items()}
    (out / "agreement.json").write_text(json.dumps(table, indent=2) + "\n", encoding="utf-8")
    cv2.imwrite(str(out / "agreement.png"), agreement_figure(results))
    floor = agreement(feature_pairs(scenes, scaling, "truth"))
    truth_table = {f: r.to_json() for f, r in floor.items()}
    (out / "agreement_truth.json").write_text(
        json.dumps(truth_table, indent=2) + "\n", encoding="utf-8"
    )
    return table
