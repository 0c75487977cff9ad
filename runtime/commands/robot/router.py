"""``percept router``: run the lab's Zenoh router with mutual TLS and access control."""

from __future__ import annotations

import argparse
import signal
import sys
import threading

NAME = "router"
HELP = "run the lab Zenoh router: mutual TLS, each robot may publish only under its own name"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", required=True, metavar="TOML", help="router file (see README)")


def run(args: argparse.Namespace) -> int:
    import zenoh

    from percept.runtime.net.router import RouterError, load_router_settings, serve

    settings = load_router_settings(args.config)
    # Zenoh's own warnings name refused links (unknown CA, missing certificate); RUST_LOG overrides.
    zenoh.init_log_from_env_or("warn")
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        serve(settings, stop)
    except RouterError as err:
        print(f"percept router: {err}", file=sys.stderr)
        return 1
    return 0
