"""``percept look``: turn a robot's head once so that it looks at a point (a gaze check).

On hardware, or on ``percept emulate-servos`` (``--port``). It moves servos, so it refuses
unless the experiment's ``[gaze]`` table says ``enabled = true`` or ``--enable-gaze`` is given.
It waits until the head has settled, prints where it looks, and stops as ``torque_at_stop``
says (hold or release); SIGINT/SIGTERM stop it the same way on the spot. Killed outright, the
Protocol 2.0 bus watchdog stops the head.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from percept.runtime.commands.bringup._servos import load_servo_profile

if TYPE_CHECKING:
    from percept.drivers.dynamixel.bus import DynamixelBus
    from percept.drivers.dynamixel.settings import GazeSettings
    from percept.kinematics.gaze import Vec3
    from percept.runtime.daemon.gaze import Gaze
    from percept.runtime.net.codec import JSON
    from percept.runtime.settings.profile import PlatformProfile

NAME = "look"
HELP = "turn a robot's head to look at a point X Y [Z] of its ground frame (moves servos)"

EXIT_NOT_THERE = 1
EXIT_REFUSED = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", metavar="TOML", required=True, help="platform profile")
    p.add_argument(
        "--at",
        nargs="+",
        type=float,
        required=True,
        metavar="M",
        help="X Y [Z]: the point to look at in the robot's ground frame, metres (Z default 0)",
    )
    p.add_argument(
        "--experiment",
        metavar="TOML",
        help="experiment whose [gaze] table applies (default: gaze settings' defaults, off)",
    )
    p.add_argument(
        "--enable-gaze",
        action="store_true",
        help="move the servos even though the experiment's [gaze] enabled is false",
    )
    p.add_argument("--port", metavar="PATH", help="serial port instead of the profile's bus.port")
    p.add_argument(
        "--speed", type=float, metavar="RAD_S", help="joint speed (default: [gaze] max_speed)"
    )
    p.add_argument(
        "--wait",
        type=float,
        metavar="SECONDS",
        help="how long to wait for the head to settle (default: the travel time plus 3 s)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    from percept.drivers.dynamixel.bus import DynamixelBus
    from percept.kinematics.gaze import off_axis
    from percept.kinematics.tree import KinematicTree
    from percept.runtime.daemon.gaze import Gaze

    problem = _bad_numbers(args)
    if problem is not None:  # before any servo is opened, let alone turned on
        print(f"percept look: {problem}", file=sys.stderr)
        return EXIT_REFUSED
    target = (args.at[0], args.at[1], args.at[2] if len(args.at) == 3 else 0.0)
    profile = load_servo_profile(args.robot)
    settings = _gaze_settings(args, profile)
    if settings is None:
        return EXIT_REFUSED
    bus_settings = dataclasses.replace(profile.bus, port=args.port or profile.bus.port)
    tree = KinematicTree.from_settings(profile.kinematics)
    try:
        bus = DynamixelBus(bus_settings, profile.joints, gaze=settings)
    except ValueError as err:  # a gaze joint without a servo, a watchdog too short
        print(f"percept look: {err}", file=sys.stderr)
        return EXIT_REFUSED
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    with bus:
        looked = _look(bus, Gaze(bus, tree, profile.joints, settings), target, args, stop)
    if isinstance(looked, int):
        return looked
    error = math.degrees(off_axis(tree, looked.angles, target))
    _print_report(args, looked, target, error, settings)
    if not looked.settled:
        why = looked.status["problem"] or ("stopped by a signal" if stop.is_set() else "timed out")
        print(f"percept look: the head did not settle: {why}", file=sys.stderr)
        return EXIT_NOT_THERE
    return 0


def _bad_numbers(args: argparse.Namespace) -> str | None:
    """What is wrong with the numbers given, or None: ``--at`` two or three finite
    coordinates, ``--speed`` a finite speed above 0, ``--wait`` finite and not negative."""
    if len(args.at) not in (2, 3):
        return "--at takes X Y or X Y Z"
    if not all(math.isfinite(c) for c in args.at):
        return f"--at: {' '.join(map(str, args.at))} is not a point (finite metres expected)"
    if args.speed is not None and not (math.isfinite(args.speed) and args.speed > 0):
        return f"--speed: {args.speed} is not a speed (a finite number of rad/s above 0)"
    if args.wait is not None and not (math.isfinite(args.wait) and args.wait >= 0):
        return f"--wait: {args.wait} is not a wait (a finite number of seconds, 0 or more)"
    return None


def _gaze_settings(args: argparse.Namespace, profile: PlatformProfile) -> GazeSettings | None:
    """The experiment's gaze settings, enabled; None (after saying why) when gaze is not
    enabled and ``--enable-gaze`` not given."""
    from percept.drivers.dynamixel.settings import GazeSettings
    from percept.runtime.settings.experiment import check_gaze, load_experiment

    experiment = load_experiment(args.experiment) if args.experiment is not None else None
    settings = experiment.gaze if experiment is not None else GazeSettings()
    if not settings.enabled and not args.enable_gaze:
        where = args.experiment or "the default gaze settings"
        print(
            f"percept look: gaze is not enabled in {where} ([gaze] enabled = false): nothing "
            "moves; pass --enable-gaze to move the head anyway",
            file=sys.stderr,
        )
        return None
    settings = dataclasses.replace(settings, enabled=True)
    if experiment is not None:
        check_gaze(args.experiment, dataclasses.replace(experiment, gaze=settings), profile)
    return settings


@dataclass(frozen=True)
class _Looked:
    """How a look went: whether the head settled, in how long, where it ended up and the
    gaze status then."""

    settled: bool
    seconds: float
    angles: dict[str, float]
    status: dict[str, JSON]


def _look(
    bus: DynamixelBus,
    gaze: Gaze,
    target: Vec3,
    args: argparse.Namespace,
    stop: threading.Event,
) -> _Looked | int:
    """Turn the head to ``target`` and wait until it settles; an exit code when there is no
    reading from the bus or the target cannot be faced."""
    from percept.kinematics.gaze import Unreachable

    began = time.monotonic()
    while bus.latest() is None and not stop.is_set() and time.monotonic() - began < 3.0:
        stop.wait(0.01)
    if bus.latest() is None:
        why = bus.status()["problem"] or "no servo answered"
        print(f"percept look: no reading from {bus.settings.port}: {why}", file=sys.stderr)
        return EXIT_NOT_THERE
    try:
        goals = gaze.aim(target)
    except Unreachable as err:
        print(f"percept look: {err}", file=sys.stderr)
        return EXIT_NOT_THERE
    wait = args.wait if args.wait is not None else gaze.travel_time(goals) + 3.0
    began = time.monotonic()
    gaze.look_at(*target, speed=args.speed)
    settled = gaze.wait_settled(wait, stop)
    seconds = time.monotonic() - began
    sample = bus.latest()
    angles = sample.angles if sample is not None else {}
    return _Looked(settled, seconds, angles, gaze.status())


def _print_report(
    args: argparse.Namespace, looked: _Looked, target: Vec3, error: float, settings: GazeSettings
) -> None:
    angles, seconds = looked.angles, looked.seconds
    if args.json:
        report = {
            "target": list(target),
            "goals": looked.status["goals"],
            "angles": angles,
            "settled": looked.settled,
            "seconds": round(seconds, 3),
            "error_deg": round(error, 3),
            "problem": looked.status["problem"],
            "torque_at_stop": settings.torque_at_stop,
        }
        print(json.dumps(report), flush=True)
    else:
        joints = "  ".join(f"{n}={a:+.4f}" for n, a in angles.items())
        print(
            f"{'settled' if looked.settled else 'NOT settled'} after {seconds:.2f} s: {joints}  "
            f"optical axis {error:.2f} deg off ({', '.join(f'{c:g}' for c in target)})",
            flush=True,
        )
