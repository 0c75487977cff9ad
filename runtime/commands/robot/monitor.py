"""``percept monitor``: the joint-attention monitor of an experiment."""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import threading
import time

NAME = "monitor"
HELP = "watch all robots' world models; announce joint attention and start games while it lasts"

WAIT_REPORT = 1.0  # seconds between two looks at what the monitor waits for


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

    robots = [r.name for r in experiment.robots]
    with Link(experiment, args.name or experiment.peers.monitor) as link:
        service = MonitorService(
            link, robots, experiment.peers, emit, start_games=not args.no_start
        )
        # The events go to stdout as JSON lines; what it waits for meanwhile to stderr, each
        # time that changes, so that a monitor with nothing to announce does not look dead.
        tell(f"watching robots {', '.join(robots)} on keys {link.prefix}/*; events on stdout")
        said = ""
        ends = time.monotonic() + (math.inf if args.seconds is None else args.seconds)
        while not stop.wait(max(0.0, min(WAIT_REPORT, ends - time.monotonic()))):
            if time.monotonic() >= ends:
                break
            now = service.monitor.waiting_for()
            if now != said:
                tell(now)
                said = now
    return 0


def tell(text: str) -> None:
    print(f"percept monitor: {text}", file=sys.stderr, flush=True)
