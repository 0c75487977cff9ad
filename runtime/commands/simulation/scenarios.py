"""``percept scenarios``: scene files drawn at random from a distribution of scenes.

``DIR/NAME-SEED.toml`` for the seeds ``S`` to ``S + N - 1`` (scene ``k`` is drawn from seed
``k`` alone, so it is the same in every batch that holds it), each a scene for ``percept sim``
whose robots name their profiles by shipped name or by a path from ``DIR``. Every file is read
back through the scene loader before the command ends. Prints one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

NAME = "scenarios"
HELP = "write random scene files drawn from a distribution of scenes (a robustness test set)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--count", type=int, required=True, metavar="N", help="scenes to write")
    p.add_argument("--seed", type=int, required=True, metavar="S", help="seed of the first scene")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument(
        "--distribution",
        default="default",
        metavar="FILE",
        help="distribution file or shipped name (default: default, config/scenarios)",
    )


def profile_names(dist_path: Path, profiles: dict[str, str], out: Path) -> dict[str, str]:
    """What each robot's ``profile`` key says in a scene file in ``out``: a shipped name as it
    is, a path (relative to the distribution file) as a path from ``out``."""
    from percept.config import shipped

    names: dict[str, str] = {}
    for robot, profile in profiles.items():
        if profile in shipped("robots"):
            names[robot] = profile
        else:
            target = (dist_path.parent / profile).resolve()
            names[robot] = os.path.relpath(target, out.resolve())
    return names


def run(args: argparse.Namespace) -> int:
    from percept.config import find
    from percept.config.loader import ConfigError, load
    from percept.config.writer import dumps
    from percept.drivers.sim.scenarios.distribution import Distribution
    from percept.drivers.sim.scenarios.draw import draw_scene
    from percept.runtime.settings.scene import load_scene

    if args.count < 1 or args.seed < 0:
        print("percept scenarios: --count must be at least 1 and --seed not negative")
        return 2
    path = find("scenarios", args.distribution)
    dist = load(Distribution, path)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    profiles = profile_names(path, {r.name: r.profile for r in dist.robots}, out)
    written = []
    for seed in range(args.seed, args.seed + args.count):
        scenario = draw_scene(dist, seed, profiles)
        file = out / f"{scenario.data['name']}.toml"
        file.write_text(dumps(scenario.data, scenario.header), encoding="utf-8")
        try:
            load_scene(file)
        except ConfigError as err:  # a distribution that draws impossible scenes
            problem = f"seed {seed} drew a scene that does not load: {err}"
            raise ConfigError(path, "", problem) from None
        written.append(file.name)
    print(json.dumps({"out": str(out), "distribution": str(path), "scenes": written}))
    return 0
