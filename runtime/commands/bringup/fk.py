"""``percept fk``: the camera pose of a robot for given joint angles, in its ground frame."""

from __future__ import annotations

import argparse
import json
import sys

from percept.runtime.commands.bringup._joint_angles import add_set_option, parse_angles

NAME = "fk"
HELP = "print the camera pose (R, t) in the robot's ground frame for given joint angles"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", required=True, metavar="TOML", help="platform profile")
    add_set_option(p, "a joint angle (repeatable); joints not set are 0")
    p.add_argument(
        "--json",
        action="store_true",
        help='print {"R": 3x3, "t": [x, y, z], "frame": "ground"}; R maps the camera frame '
        "(x optical axis, y left, z up) into the ground frame",
    )


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from percept.config.loader import ConfigError
    from percept.kinematics.tree import KinematicsError, KinematicTree
    from percept.runtime.settings.profile import load_profile

    profile = load_profile(args.robot)
    try:
        tree = KinematicTree.from_settings(profile.kinematics)
    except KinematicsError as err:
        raise ConfigError(args.robot, "kinematics", str(err)) from None
    try:
        angles = parse_angles(args.set, tree.movable_joints)
    except ValueError as err:
        print(f"percept fk: {err}", file=sys.stderr)
        return 2
    pose = tree.camera_pose(angles)
    if args.json:
        print(json.dumps(pose.as_dict()))
        return 0
    rows = "\n".join("  [" + ", ".join(f"{v:+.6f}" for v in row) + "]" for row in pose.R)
    used = ", ".join(f"{n}={angles.get(n, 0.0):+.4f}" for n in tree.camera_joints) or "(none)"
    optical = pose.R[:, 0]
    print(f"robot {profile.name}: camera link {profile.kinematics.camera_link}")
    print(f"joints: {used}")
    print("t (camera centre in the ground frame, m): " + ", ".join(f"{v:+.4f}" for v in pose.t))
    print(f"R (camera frame -> ground frame):\n{rows}")
    pitch = float(np.degrees(np.arcsin(np.clip(optical[2], -1.0, 1.0))))
    yaw = float(np.degrees(np.arctan2(optical[1], optical[0])))
    print(f"optical axis: {yaw:+.1f} deg left of x, {pitch:+.1f} deg above the horizon")
    return 0
