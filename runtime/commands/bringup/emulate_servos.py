"""``percept emulate-servos``: a robot's Dynamixel servos on a pseudo-terminal."""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from percept.runtime.commands.bringup._joint_angles import add_set_option, parse_angles
from percept.runtime.commands.bringup._servos import load_servo_profile

NAME = "emulate-servos"
HELP = (
    "emulate a robot profile's Dynamixel servos on a pseudo-terminal; prints the port path "
    "first, runs until SIGINT/SIGTERM"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", metavar="TOML", required=True, help="platform profile")
    add_set_option(p, "initial joint angle (repeatable); joints not set start at their zero tick")
    p.add_argument(
        "--link", metavar="PATH", help="port path to create (a symlink); default: a temporary one"
    )
    p.add_argument(
        "--play",
        metavar="CSV",
        help="play back recorded joint angles (a t column and one column per joint, as percept "
        "sim's joints.csv): those servos report the recording at its times; goals are accepted "
        "but do not move them",
    )
    p.add_argument(
        "--epoch",
        type=float,
        metavar="SECONDS",
        help="with --play: wall-clock time (Unix seconds) of the recording's first row "
        "(default: when the emulator starts)",
    )


def run(args: argparse.Namespace) -> int:
    import time

    from percept.drivers.dynamixel.emulator import ServoEmulator
    from percept.drivers.dynamixel.playback import read_recording

    profile = load_servo_profile(args.robot)
    if args.epoch is not None and args.play is None:
        print("percept emulate-servos: --epoch needs --play", file=sys.stderr)
        return 2
    try:
        angles = parse_angles(args.set, (j.name for j in profile.joints))
        recording = None
        if args.play is not None:
            recording = read_recording(args.play, (j.name for j in profile.joints))
        emulator = ServoEmulator.for_profile(
            profile.joints, profile.bus.protocol, baudrate=profile.bus.baudrate, link=args.link
        )
    except ValueError as err:  # a RecordingError too
        print(f"percept emulate-servos: {err}", file=sys.stderr)
        return 2
    for name, angle in angles.items():
        emulator.set_angle(name, angle)
    if recording is not None:
        emulator.play(recording, time.time() if args.epoch is None else args.epoch)
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    with emulator:
        print(emulator.port_path, flush=True)
        done.wait()
    return 0
