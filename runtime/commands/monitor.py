"""``percept monitor``: the joint-attention monitor of an experiment."""

from __future__ import annotations

import argparse
import json
import signal
import threading

NAME = "monitor"
HELP = "watch all robots' world models; announce joint attention and start games while it lasts"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--experiment", required=True, metavar="TOML", help="experiment file")
    p.add_argument(
        "--name",
        help="this program's name in Zenoh keys (default: the experiment's [peers] monitor, "
        "the only name besides the players' whose start signals the robots heed)",
    )
    p.add_argument("--no-start", action="store_true", help="only announce; do not start games")
    p.add_argument("--seconds", type=float, metavar="T", help="stop after T seconds")


def run(args: argparse.Namespace) -> int:
    from percept.runtime.games.monitor import AttentionEvent, MonitorService
    from percept.runtime.net.link import Link
    from percept.runtime.settings.experiment import load_experiment

    experiment = load_experiment(args.experiment)
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())

    def emit(event: AttentionEvent) -> None:
        print(json.dumps(event), flush=True)

    with Link(experiment, args.name or experiment.peers.monitor) as link:
        MonitorService(
            link,
            [r.name for r in experiment.robots],
            experiment.peers,
            emit,
            start_games=not args.no_start,
        )
        stop.wait(args.seconds)
    return 0
