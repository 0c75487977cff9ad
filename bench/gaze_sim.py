"""Look-at accuracy and settling time in the simulated world (issue 17 targets).

Robot a of ``tabletop-basic`` (a ROBOTIS OP3) with gaze on, the whole chain real: percept's
:class:`~percept.runtime.daemon.gaze.Gaze` (inverse kinematics) -> the Dynamixel driver's sync
writes through dynamixel-sdk -> the servo emulator on a pty (servos moving at the profile
velocity) -> the simulated head following the emulated servos -> MuJoCo's camera, the truth.
For floor points spread over +-``--spread`` degrees at 0.6-1.2 m (visited in a shuffled order,
so the head travels between them), it measures:

- the look-at error: the angle between the true camera's optical axis and the direction to the
  target once settled (``--hold`` seconds after the command's allowed time),
- the settling time: from the command until the true error stays below 1 degree (and 0.1
  degree), against the time the servo speed allows (largest joint travel / ``--speed``) plus
  100 ms.

    MUJOCO_GL=egl python bench/gaze_sim.py [--speed 1.0] [--spread 40] [--seed 17]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from percept.drivers.dynamixel.bus import DynamixelBus
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.settings import GazeSettings
from percept.drivers.sim.clock import WallClock
from percept.drivers.sim.joints import EmulatorBridge
from percept.kinematics.tree import KinematicTree
from percept.runtime.daemon.gaze import Gaze
from percept.runtime.settings.profile import load_profile
from percept.runtime.settings.scene import open_world

ROBOT = "a"
TARGET_ERROR = 1.0  # degrees
TARGET_SLACK = 0.1  # seconds beyond what the servo speed allows


def true_error(world, t: float, target: tuple[float, float, float]) -> float:
    """Degrees between MuJoCo's camera axis and the direction to ``target`` (ground frame)."""
    camera = world.truth(t, views=()).robots[ROBOT].camera
    d = np.asarray(target) - camera.t
    return math.degrees(math.acos(float(np.clip(camera.R[:, 0] @ d / np.linalg.norm(d), -1, 1))))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=1.0, help="[gaze] max_speed, rad/s")
    parser.add_argument("--spread", type=float, default=40.0, help="degrees either side")
    parser.add_argument("--hold", type=float, default=0.3, help="seconds after the allowed time")
    parser.add_argument("--seed", type=int, default=17)
    parser.add_argument("--json", action="store_true", help="one JSON object per target too")
    args = parser.parse_args()

    world = open_world("tabletop-basic")
    profile = load_profile("robotis-op3")  # the scene's robot a
    gaze_settings = GazeSettings(enabled=True, max_speed=args.speed, watchdog=0.2)
    clock = WallClock(hold=True)  # scene time 0 throughout: a still scene
    emulator = ServoEmulator.for_profile(profile.joints, profile.bus.protocol).start()
    bridge = EmulatorBridge(world, ROBOT, emulator, clock, follow=gaze_settings.joints)
    bus = DynamixelBus(
        replace(profile.bus, port=emulator.port_path), profile.joints, gaze=gaze_settings
    )
    tree = KinematicTree.from_settings(profile.kinematics)
    gaze = Gaze(bus, tree, profile.joints, gaze_settings)
    bearings = np.linspace(-args.spread, args.spread, 9)
    targets = [
        (d * math.cos(math.radians(b)), d * math.sin(math.radians(b)), 0.0)
        for b in bearings
        for d in (0.6, 0.9, 1.2)
    ]
    random.Random(args.seed).shuffle(targets)
    rows = []
    bridge.start()
    bus.start()
    try:
        while bus.latest() is None:
            time.sleep(0.01)
        for target in targets:
            goals = gaze.aim(target)
            allowed = gaze.travel_time(goals)
            began = time.monotonic()
            gaze.look_at(*target)
            samples = []
            while (now := time.monotonic()) < began + allowed + args.hold + 0.5:
                samples.append((now - began, true_error(world, 0.0, target)))
                time.sleep(0.002)
            settle = max((t for t, e in samples if e >= TARGET_ERROR), default=0.0)
            exact = max((t for t, e in samples if e >= 0.1), default=0.0)
            final = samples[-1][1]
            rows.append(
                {
                    "target": [round(c, 3) for c in target],
                    "allowed_s": round(allowed, 3),
                    "settle_s": round(settle, 3),
                    "late_s": round(settle - allowed, 3),
                    "late_0.1deg_s": round(exact - allowed, 3),
                    "error_deg": round(final, 3),
                }
            )
            if args.json:
                print(json.dumps(rows[-1]))
    finally:
        bus.stop()
        bridge.stop()
        emulator.stop()
        world.close()
    errors = [r["error_deg"] for r in rows]
    late = [r["late_s"] for r in rows]
    exact = [r["late_0.1deg_s"] for r in rows]
    met_error = sum(e < TARGET_ERROR for e in errors)
    met_time = sum(x <= TARGET_SLACK for x in late)
    print(
        f"{len(rows)} targets over +-{args.spread:g} deg at 0.6-1.2 m, speed {args.speed:g} rad/s\n"
        f"look-at error once settled: median {statistics.median(errors):.3f} deg, "
        f"max {max(errors):.3f} deg; < {TARGET_ERROR:g} deg: {met_error}/{len(rows)}\n"
        f"settling beyond the time the speed allows: median {statistics.median(late) * 1000:.0f}"
        f" ms, p90 {np.percentile(late, 90) * 1000:.0f} ms, max {max(late) * 1000:.0f} ms; "
        f"<= {TARGET_SLACK * 1000:.0f} ms: {met_time}/{len(rows)}\n"
        f"to within 0.1 deg: median {statistics.median(exact) * 1000:.0f} ms, "
        f"max {max(exact) * 1000:.0f} ms beyond the allowed time"
    )
    return 0 if met_error == met_time == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
