"""``percept calibrate-head``: the camera's pose on its link, the head joints' zero offsets and the
delay between frames and joint readings, measured by the robot itself.

The head sweeps a grid of poses over a static scene with the experiment's marker boxes; one
least-squares problem over the marker corners of all frames
(:func:`percept.kinematics.calibration.calibrate_head`) gives the estimates with their
uncertainties, and a corrected copy of the profile is written (the original is never touched).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from percept.kinematics.calibration import HeadCalibration
    from percept.runtime.commands.bringup._head_sweep import Sweep

NAME = "calibrate-head"
HELP = "estimate the camera's mounting, the head joints' zeros and the joint delay from a sweep"

EXIT_REFUSED = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", required=True, metavar="PROFILE", help="platform profile to correct")
    p.add_argument(
        "--experiment",
        default="tabletop",
        metavar="E",
        help="experiment whose [landmarks] boxes the sweep sees (default tabletop)",
    )
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--sim", metavar="SCENE", help="sweep in this simulated scene")
    source.add_argument(
        "--from-recording", metavar="REC", help="solve offline from a recording of a sweep"
    )
    p.add_argument("--name", default="a", help="--sim: the robot in the scene (default a)")
    p.add_argument("--out", required=True, metavar="CORRECTED.toml", help="corrected profile")
    p.add_argument(
        "--box-at",
        nargs=4,
        action="append",
        type=float,
        default=[],
        metavar=("ID", "X", "Y", "HEADING"),
        help="a box's measured floor pose in the robot's ground frame (m, m, rad); repeatable. "
        "--sim: the scene's box poses unless --unmeasured",
    )
    p.add_argument(
        "--unmeasured",
        action="store_true",
        help="--sim: estimate every box's pose (no box measured)",
    )
    p.add_argument("--pan", nargs=2, type=float, metavar=("LO", "HI"), help="pan range, rad")
    p.add_argument("--tilt", nargs=2, type=float, metavar=("LO", "HI"), help="tilt range, rad")
    p.add_argument(
        "--steps",
        nargs=2,
        type=int,
        default=(5, 3),
        metavar=("PAN", "TILT"),
        help="head poses across and down the grid (default 5 3)",
    )
    p.add_argument(
        "--speed", type=float, default=0.5, help="--sim: head speed, rad/s (default 0.5)"
    )
    p.add_argument("--fps", type=float, default=15.0, help="--sim: frames per second (default 15)")
    p.add_argument(
        "--max-duration",
        type=float,
        default=60.0,
        metavar="S",
        help="--sim: longest sweep, seconds (default 60)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON line")


def run(args: argparse.Namespace) -> int:
    from percept.kinematics.calibration import CalibrationRefused

    try:
        return _run(args)
    except CalibrationRefused as err:
        print(f"percept calibrate-head: refused: {err}", file=sys.stderr)
        return EXIT_REFUSED


def _run(args: argparse.Namespace) -> int:
    from percept.config import find
    from percept.kinematics.calibration import calibrate_head
    from percept.kinematics.camera import CameraModel
    from percept.kinematics.pose import ground_transform
    from percept.kinematics.tree import KinematicTree
    from percept.runtime.commands.bringup._head_sweep import (
        box_markers,
        head_limits,
        recorded_sweep,
        sim_sweep,
    )
    from percept.runtime.settings.experiment import load_experiment
    from percept.runtime.settings.profile import load_profile

    profile_path = find("robots", args.robot)
    profile = load_profile(profile_path)
    experiment = load_experiment(find("experiments", args.experiment))
    tree = KinematicTree.from_settings(profile.kinematics)
    cam = profile.camera
    lens = CameraModel.from_lens(cam.lens, cam.width, cam.height)
    markers = box_markers(experiment.landmarks)
    measured = {int(b): ground_transform(x, y, h) for b, x, y, h in args.box_at}
    if args.sim:
        from percept.kinematics.gaze import sweep_grid
        from percept.runtime.settings.scene import find_scene

        limits = head_limits(profile, experiment.gaze.joints)
        poses = sweep_grid(limits, args.pan, args.tilt, tuple(args.steps))
        sweep, boxes = sim_sweep(
            find_scene(args.sim),
            args.name,
            profile,
            experiment.landmarks,
            poses,
            args.speed,
            args.fps,
        )
        if sweep.duration > args.max_duration:
            print(
                f"percept calibrate-head: the sweep takes {sweep.duration:.0f} s, more than "
                f"--max-duration {args.max_duration:.0f}: fewer --steps or a faster --speed",
                file=sys.stderr,
            )
            return EXIT_REFUSED
        if not args.box_at and not args.unmeasured:
            measured = boxes
    else:
        sweep = recorded_sweep(Path(args.from_recording), experiment.landmarks)
    result = calibrate_head(tree, lens, sweep.sightings, sweep.readings, markers, measured)
    from percept.runtime.settings.corrected import calibrated_profile, write_corrected

    text = calibrated_profile(profile_path.read_text(encoding="utf-8"), tree, result)
    write_corrected(profile_path, Path(args.out), text)
    if args.json:
        print(json.dumps(_summary(result, sweep)))
    else:
        print(_report(result, sweep, args.out))
    return 0


def _summary(result: HeadCalibration, sweep: Sweep) -> dict[str, object]:
    """The ``--json`` line: the estimated perturbation, its uncertainties, the errors."""
    return {
        "camera_offset": [e.value for e in result.camera_offset],
        "camera_rotation": [e.value for e in result.camera_rotation],
        "joint_zero": {n: e.value for n, e in result.joint_zero.items()},
        "delay": result.delay.value,
        "reprojection_px_before": result.reprojection_px_before,
        "reprojection_px_after": result.reprojection_px_after,
        "sigma": {
            "camera_offset": [e.sigma for e in result.camera_offset],
            "camera_rotation": [e.sigma for e in result.camera_rotation],
            "joint_zero": {n: e.sigma for n, e in result.joint_zero.items()},
            "delay": result.delay.sigma,
        },
        "folded_into_mounting": list(result.folded),
        "boxes": {str(b): list(p) for b, p in result.bodies.items()},
        "frames": result.frames,
        "sightings": result.sightings,
        "sweep_s": sweep.duration,
    }


def _report(result: HeadCalibration, sweep: Sweep, out: str) -> str:
    """The report for a person."""
    o, r = result.camera_offset, result.camera_rotation
    lines = [
        f"sweep: {sweep.duration:.1f} s, {sweep.frames} frames, markers in {result.frames} "
        f"({result.sightings} sightings)",
        "camera on its link (x forward, y left, z up):",
        *(
            f"  offset {a}: {e.value * 1000:+7.2f} mm  +- {e.sigma * 1000:.2f}"
            for a, e in zip("xyz", o, strict=True)
        ),
        *(
            f"  {a:5s}:    {math.degrees(e.value):+7.3f} deg +- {math.degrees(e.sigma):.3f}"
            for a, e in zip(("roll", "pitch", "yaw"), r, strict=True)
        ),
        "joint zeros (a joint reads this much more than it stands):",
        *(
            f"  {n}: {math.degrees(e.value):+7.3f} deg +- {math.degrees(e.sigma):.3f}"
            for n, e in result.joint_zero.items()
        ),
        *(
            f"  {n}: folded into the camera's mounting (the same camera pose at every angle)"
            for n in result.folded
        ),
        f"delay (readings behind the frames): {result.delay.value * 1000:+.1f} ms "
        f"+- {result.delay.sigma * 1000:.1f}",
        f"reprojection error (median): {result.reprojection_px_before:.2f} px before, "
        f"{result.reprojection_px_after:.2f} px after",
        f"corrected profile: {out}",
    ]
    return "\n".join(lines)
