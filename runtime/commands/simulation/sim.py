"""``percept sim``: render one robot's view of a scene, with ground truth, as a MOTChallenge
sequence folder."""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING

from percept.runtime.commands._sequence import SIM_SECTION

if TYPE_CHECKING:
    from percept.drivers.sim.world import SimWorld

NAME = "sim"
HELP = "render a robot's camera in a simulated scene, with ground truth (MOTChallenge folder)"

log = logging.getLogger("percept.sim")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--scene", required=True, help="scene name in config/scenes (e.g. tabletop-basic) or file"
    )
    p.add_argument("--robot", required=True, help="the robot of the scene whose camera to render")
    p.add_argument("--out", required=True, type=Path, help="output folder (a sequence folder)")
    p.add_argument(
        "--seconds", type=float, help="scene seconds to render (default: the scene's duration)"
    )
    p.add_argument("--fps", type=float, help="frames per second (default: the profile's camera)")
    p.add_argument("--seed", type=int, help="override the scene's seed (textures, noise)")
    p.add_argument("--start", type=float, default=0.0, help="scene time of the first frame")
    p.add_argument(
        "--min-pixels",
        type=int,
        default=10,
        help="gt.txt lists an object in a frame when at least this many of its pixels show",
    )


def _seqinfo(
    name: str,
    fps: float,
    frames: int,
    width: int,
    height: int,
    calibration: int,
    simulated: dict[str, str],
) -> str:
    """MOTChallenge's sequence file. ``calibrationFrames`` (percept's own key, when the scene says
    how long its calibration is) tells ``percept track`` how many frames calibrate; a section of
    percept's says what was simulated (``percept track`` finds the robot's profile for
    ``joints.csv`` there)."""
    extra = f"calibrationFrames={calibration}\n" if calibration else ""
    return (
        "[Sequence]\n"
        f"name={name}\nimDir=img1\nframeRate={fps:g}\nseqLength={frames}\n"
        f"imWidth={width}\nimHeight={height}\nimExt=.png\n{extra}"
        f"\n[{SIM_SECTION}]\n" + "".join(f"{k}={v}\n" for k, v in simulated.items())
    )


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from percept.config import portable_name
    from percept.config.loader import ConfigError
    from percept.drivers.sim.scene import SceneError
    from percept.drivers.sim.world import SimWorld
    from percept.kinematics.camera import save_intrinsics
    from percept.runtime.settings.scene import find_scene, load_scene, robot_profile

    path = find_scene(args.scene)
    scene, platforms = load_scene(path)
    if args.seed is not None:
        scene = dataclasses.replace(scene, seed=args.seed)
    if args.robot not in [r.name for r in scene.robots]:
        known = ", ".join(r.name for r in scene.robots)
        raise ConfigError(path, "robots", f"no robot {args.robot!r} in the scene (it has {known})")
    camera = platforms[args.robot].camera
    fps = args.fps or camera.fps
    seconds = scene.duration if args.seconds is None else args.seconds
    if fps <= 0 or seconds < 0:
        print("percept sim: --fps must be positive and --seconds not negative")
        return 2
    frames = round(seconds * fps)
    out: Path = args.out
    (out / "img1").mkdir(parents=True, exist_ok=True)
    (out / "gt").mkdir(exist_ok=True)
    try:
        world = SimWorld(scene, platforms)
    except SceneError as err:
        raise ConfigError(path, err.key, err.problem) from None
    joint_names = world.robot_model(args.robot).tree.movable_joints
    log.info(
        "scene %s, robot %s: %d frames at %g fps (%dx%d) into %s",
        scene.name,
        args.robot,
        frames,
        fps,
        camera.width,
        camera.height,
        out,
    )
    save_intrinsics(out / "intrinsics.json", world.camera_model(args.robot))
    calibration = min(frames, round(max(0.0, scene.calibration - args.start) * fps))
    (out / "seqinfo.ini").write_text(
        _seqinfo(
            f"{scene.name}-{args.robot}",
            fps,
            frames,
            camera.width,
            camera.height,
            calibration,
            {
                "scene": portable_name("scenes", path),
                "robot": args.robot,
                "profile": portable_name("robots", robot_profile(scene.robot(args.robot))),
            },
        ),
        encoding="utf-8",
    )
    began = time.perf_counter()
    with world:
        render_s, truth_s = _render(world, args, joint_names, fps, frames)
    elapsed = time.perf_counter() - began
    per = 1000 / max(frames, 1)
    log.info(
        "%d frames in %.1f s: render %.2f ms/frame, truth %.2f ms/frame",
        frames,
        elapsed,
        render_s * per,
        truth_s * per,
    )
    print(json.dumps({"out": str(out), "frames": frames, "fps": fps, "seconds": seconds}))
    return 0


def _render(
    world: SimWorld,
    args: argparse.Namespace,
    joint_names: list[str],
    fps: float,
    frames: int,
) -> tuple[float, float]:
    """Render the frames into ``args.out`` with their truth (``truth.jsonl``, ``gt/gt.txt``,
    ``joints.csv``); returns the seconds spent rendering and computing the truth."""
    import cv2

    from percept.perception.evaluation.tracking import mot_box

    out: Path = args.out
    render_s = truth_s = 0.0
    with (
        (out / "truth.jsonl").open("w", encoding="utf-8") as truth_file,
        (out / "gt" / "gt.txt").open("w", encoding="utf-8") as gt_file,
        (out / "joints.csv").open("w", encoding="utf-8") as joints_file,
    ):
        joints_file.write(",".join(["frame", "t", *joint_names]) + "\n")
        for k in range(1, frames + 1):
            t = args.start + (k - 1) / fps
            t0 = time.perf_counter()
            image = world.render(args.robot, t)
            t1 = time.perf_counter()
            record = world.truth(t, [args.robot]).record(args.robot)
            truth_s += time.perf_counter() - t1
            render_s += t1 - t0
            cv2.imwrite(str(out / "img1" / f"{k:06d}.png"), image)
            truth_file.write(json.dumps({"frame": k, **record}, separators=(",", ":")) + "\n")
            for o in record["objects"]:
                # a figure is a person walking through: no object to find, left out of gt.txt
                if o["shape"] != "figure" and o["bbox"] and o["pixels"] >= args.min_pixels:
                    left, top, w, h = mot_box(o["bbox"])
                    gt_file.write(f"{k},{o['id']},{left},{top},{w},{h},1,-1,-1,-1\n")
            angles = record["joints"]
            joints_file.write(
                ",".join([str(k), f"{t:.6f}", *(f"{angles[j]:.6f}" for j in joint_names)]) + "\n"
            )
            if k % 100 == 0:
                log.info("%d/%d frames", k, frames)
    return render_s, truth_s
