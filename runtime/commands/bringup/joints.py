"""``percept joints``: read a robot's joint angles through the Dynamixel driver (a wiring check)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from typing import TYPE_CHECKING

from percept.runtime.commands.bringup._servos import load_servo_profile

if TYPE_CHECKING:
    from percept.drivers.joints import JointSample

NAME = "joints"
HELP = "read and print the joint angles (radians) of a robot's Dynamixel servos"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", metavar="TOML", required=True, help="platform profile")
    p.add_argument("--port", metavar="PATH", help="serial port instead of the profile's bus.port")
    p.add_argument("--once", action="store_true", help="print one reading and exit")
    p.add_argument("--json", action="store_true", help="one JSON object per reading")
    p.add_argument(
        "--wait",
        metavar="SECONDS",
        type=float,
        default=3.0,
        help="with --once: how long to wait for the servos to answer (default 3)",
    )
    p.add_argument(
        "--every",
        metavar="SECONDS",
        type=float,
        default=0.1,
        help="without --once: print a reading this often (default 0.1)",
    )


def _line(sample: JointSample, as_json: bool) -> str:
    stale = sorted(sample.stale)
    if as_json:
        return json.dumps({"t": sample.t, "joints": sample.angles, "stale": stale})
    angles = "  ".join(f"{name}={value:+.4f}" for name, value in sample.angles.items())
    return f"t={sample.t:.3f}  {angles}" + (f"  stale: {', '.join(stale)}" if stale else "")


def run(args: argparse.Namespace) -> int:
    from percept.drivers.dynamixel.bus import DynamixelBus

    profile = load_servo_profile(args.robot)
    settings = profile.bus if not args.port else dataclasses.replace(profile.bus, port=args.port)
    names = {j.name for j in profile.joints}
    with DynamixelBus(settings, profile.joints) as bus:
        if args.once:
            deadline = time.monotonic() + args.wait
            sample = bus.latest()
            while time.monotonic() < deadline and (sample is None or set(sample.angles) < names):
                time.sleep(0.01)
                sample = bus.latest()
            if sample is None:
                status = bus.status()
                why = status["problem"] or "no servo answered"
                print(
                    f"percept joints: no reading from {settings.port} within {args.wait} s: {why}",
                    file=sys.stderr,
                )
                return 1
            print(_line(sample, args.json), flush=True)
            return 0
        last_t = None
        while True:
            time.sleep(args.every)
            sample = bus.latest()
            if sample is not None and sample.t != last_t:
                print(_line(sample, args.json), flush=True)
                last_t = sample.t
