"""What head calibration recovers, against the simulated world's perturbation as the truth.

Both robots of ``tabletop-myon-perturbed`` (MYON profile, 640x480) are built off their profile on
purpose: the camera sits 5 mm and 2 deg off its mounting, the pan servo reads 3 deg more and the
tilt servo 2 deg less than the head stands, the joint readings are 30 ms late. Each sweeps its
head over the experiment's two marker boxes (whose floor poses the scene gives, as a lab measures
them), ``percept calibrate-head``'s solver estimates the perturbation, and this prints per robot:

- each estimate's error: the pan zero, the delay, and the camera's mounting. The tilt's zero is
  the camera turned on its link about the tilt axis, so it is folded into the mounting; the
  mounting is compared with the true one carrying the true tilt zero (what it must equal), and,
  for the record, with the true one without it;
- (robot a) the ground error of floor points (percent of their distance; median and 90th
  percentile) as forward kinematics gives them with the profile as it was and with the corrected
  profile, at head poses of another sweep than the calibration's (moving and resting, so the
  delay counts);

and each robot's estimate of the other's position from the boxes, with the profile as it was and
with each robot's corrected profile. All of it with clean images and with a webcam's image
noise, blur and JPEG.

Run: ``python bench/head_calibration.py`` (about 10 minutes on a loaded 2-core machine).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support's free_port

import cv2
import numpy as np

from bench.landmarks_sim import pointing_players
from percept.config import find
from percept.drivers.sim.scene import JointMotion, Scene
from percept.drivers.sim.world import SimWorld, Truth
from percept.kinematics.calibration import HeadCalibration, calibrate_head
from percept.kinematics.camera import CameraModel
from percept.kinematics.gaze import Limits, sweep_grid, sweep_keyframes
from percept.kinematics.ground import ground_points
from percept.kinematics.pose import (
    CameraPose,
    axis_angle_matrix,
    ground_pose,
    ground_transform,
    invert,
)
from percept.kinematics.tree import KinematicTree
from percept.perception.features.experience import sensory_experience
from percept.perception.landmarks.boxes import BoxEstimator
from percept.runtime.commands.bringup._head_sweep import box_markers, sim_sweep
from percept.runtime.games.pointing import Located
from percept.runtime.net.link import Link
from percept.runtime.net.messages import PeerPose
from percept.runtime.net.peers import peer_pose
from percept.runtime.settings.corrected import calibrated_profile
from percept.runtime.settings.experiment import Experiment, RobotEntry, load_experiment
from percept.runtime.settings.profile import load_profile
from percept.runtime.settings.scene import find_scene, load_scene, open_world
from tests.support.zenoh_rig import free_port

SCENE = "tabletop-myon-perturbed"
ROBOT = "a"
FLAT = np.full((3, 16), 1 / 16)  # colour does not matter here
PAN, TILT = (0.0, 0.75), (-0.9, -0.5)  # the check sweep's range: where robot a sees the boxes


def webcam(image: np.ndarray) -> np.ndarray:
    """A webcam's troubles on a rendered frame: sensor noise, a little defocus, JPEG."""
    rng = np.random.default_rng(int(image[::37, ::41].sum()))
    noisy = image.astype(np.float32) + rng.normal(0.0, 3.0, image.shape).astype(np.float32)
    blurred = cv2.GaussianBlur(np.clip(noisy, 0, 255).astype(np.uint8), (0, 0), 0.8)
    ok, jpeg = cv2.imencode(".jpg", blurred, [cv2.IMWRITE_JPEG_QUALITY, 75])
    assert ok
    return cv2.imdecode(jpeg, cv2.IMREAD_COLOR)


def _angle_deg(R: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) / 2.0))))


def mounting_errors(
    tree: KinematicTree, result: HeadCalibration, true_mount: np.ndarray, tilt_zero: float
) -> dict[str, float]:
    """Position (mm) and angle (deg) errors of the estimated mounting against the true one
    with the tilt's zero folded in (what it must equal), and against the true one alone."""
    tilt = next(j for j in tree.joints if j.name == result.folded[0])
    link = tree.link_transform(tilt.child, {})
    B = np.linalg.inv(link) @ tree.camera_pose({}).matrix()  # tilt's child <- camera
    turn = np.eye(4)
    axis = np.asarray(tilt.axis, dtype=float)
    turn[:3, :3] = axis_angle_matrix(axis / np.linalg.norm(axis), -tilt_zero)
    same = np.linalg.inv(B) @ turn @ B @ true_mount
    found = result.mounting()
    return {
        "mounting_mm": float(np.linalg.norm(found[:3, 3] - same[:3, 3]) * 1000),
        "mounting_deg": _angle_deg(found[:3, :3].T @ same[:3, :3]),
        "mounting_mm_unfolded": float(np.linalg.norm(found[:3, 3] - true_mount[:3, 3]) * 1000),
        "mounting_deg_unfolded": _angle_deg(found[:3, :3].T @ true_mount[:3, :3]),
    }


def ground_errors(
    scene_path: Path, before: KinematicTree, after: KinematicTree, delay: float
) -> dict[str, float]:
    """Ground error over floor points seen at the head poses of a check sweep (another grid
    than the calibration's), relative to each point's distance from the camera."""
    scene, platforms = load_scene(scene_path)
    me = scene.robot(ROBOT)
    limits = {"head_pan": Limits(*PAN), "head_tilt": Limits(*TILT)}
    poses = sweep_grid(limits, (0.1, 0.65), (-0.9, -0.6), (3, 3))
    keys = sweep_keyframes(poses, 0.5, 0.3)
    motion = {n: JointMotion(keyframes=tuple(k)) for n, k in keys.items()}
    me = dataclasses.replace(me, joints=motion)
    scene = dataclasses.replace(
        scene, robots=tuple(me if r.name == ROBOT else r for r in scene.robots)
    )
    end = max(k[-1][0] for k in keys.values())
    xs, ys = np.meshgrid(np.linspace(0.5, 1.8, 14), np.linspace(-0.6, 1.2, 19))
    floor = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    errors: dict[str, list[float]] = {"before": [], "after": []}
    with SimWorld(scene, platforms) as world:
        lens: CameraModel = world.camera_model(ROBOT)
        for t in np.arange(0.0, end, 0.1):
            true_pose = world.truth(float(t), views=[]).robots[ROBOT].camera
            to_camera = np.linalg.inv(true_pose.matrix())
            uv = lens.project(floor @ to_camera[:3, :3].T + to_camera[:3, 3])
            inside = np.isfinite(uv[:, 0]) & lens.contains(uv)
            if not inside.any():
                continue
            rays = lens.pixel_rays(uv[inside])
            distance = np.linalg.norm(floor[inside, :2] - true_pose.t[:2], axis=1)
            for label, tree, late in (("before", before, 0.0), ("after", after, delay)):
                pose: CameraPose = tree.camera_pose(world.joint_readings(ROBOT, float(t) + late))
                xy, valid = ground_points(pose, rays)
                miss = np.linalg.norm(xy - floor[inside, :2], axis=1)
                errors[label] += list((100 * miss / distance)[valid])
    return {
        f"ground_error_pct_{k}_{q}": float(np.percentile(v, p))
        for k, v in errors.items()
        for q, p in (("median", 50), ("p90", 90))
    }


def calibrate(
    robot: str, degrade: str, steps: tuple[int, int], fps: float
) -> tuple[HeadCalibration, KinematicTree, dict[str, float]]:
    """Robot ``robot``'s sweep and calibration: the result, its corrected chain (through the
    written profile), and the sweep's figures."""
    profile_path = find("robots", "myon")
    profile = load_profile(profile_path)
    experiment = load_experiment(find("experiments", "tabletop"))
    scene_path = find_scene(SCENE)
    tree = KinematicTree.from_settings(profile.kinematics)
    cam = profile.camera
    lens = CameraModel.from_lens(cam.lens, cam.width, cam.height)
    scene, _ = load_scene(scene_path)
    pan = _pan_towards_boxes(scene, robot)
    limits = {"head_pan": Limits(*pan), "head_tilt": Limits(*TILT)}
    began = time.perf_counter()
    sweep, boxes = sim_sweep(
        scene_path,
        robot,
        profile,
        experiment.landmarks,
        sweep_grid(limits, steps=steps),
        speed=0.5,
        fps=fps,
        degrade=webcam if degrade == "webcam" else None,
    )
    swept = time.perf_counter()
    result = calibrate_head(
        tree, lens, sweep.sightings, sweep.readings, box_markers(experiment.landmarks), boxes
    )
    solved = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        corrected_path = Path(tmp) / "myon-corrected.toml"
        text = calibrated_profile(profile_path.read_text(encoding="utf-8"), tree, result)
        corrected_path.write_text(text, encoding="utf-8")
        corrected = KinematicTree.from_settings(load_profile(corrected_path).kinematics)
    figures = {
        "sweep_s": round(sweep.duration, 1),
        "frames": sweep.frames,
        "frames_with_markers": result.frames,
        "render_detect_s": round(swept - began, 1),
        "solve_s": round(solved - swept, 1),
    }
    return result, corrected, figures


def _pan_towards_boxes(scene: Scene, robot: str) -> tuple[float, float]:
    """A pan range over the boxes' bearings from ``robot``, 0.2 rad beyond them each way."""
    to_robot = invert(ground_transform(*scene.robot(robot).pose))
    bearings = [
        math.atan2(float(p[1]), float(p[0]))
        for p in (to_robot @ np.array([b.pose[0], b.pose[1], 0.0, 1.0]) for b in scene.boxes)
    ]
    return max(min(bearings) - 0.2, -1.3), min(max(bearings) + 0.2, 1.3)


def peers_and_pointing(
    before: dict[str, KinematicTree],
    after: dict[str, KinematicTree],
    delay: dict[str, float],
    games: int,
) -> dict[str, float]:
    """With the profile as it was and with each robot's corrected profile: each robot's
    estimate of the other's position (m, the worst over both ways and ten frames at the scene's
    own head poses) from the boxes as each sees them, and pointing games played each way between
    two real Zenoh sessions on 127.0.0.1 over the objects each sees whole (as
    bench/landmarks_sim.py plays them)."""
    experiment = load_experiment(find("experiments", "tabletop"))
    local = Experiment(
        name="bench",
        robots=tuple(
            RobotEntry(n, experiment.robot(n).profile, f"tcp/127.0.0.1:{free_port()}") for n in "ab"
        ),
        peers=dataclasses.replace(experiment.peers, answer_timeout=5.0),
    )
    worlds: dict[str, list[Located]] = {"a": [], "b": []}
    poses: dict[str, PeerPose | None] = {"a": None, "b": None}
    out: dict[str, float] = {}
    with (
        open_world(SCENE) as world,
        Link(local, "a") as link_a,
        Link(local, "b") as link_b,
    ):
        players = pointing_players(
            {"a": link_a, "b": link_b}, worlds, poses, local, "head-calibration"
        )
        for label, trees, late in (
            ("before", before, dict.fromkeys(delay, 0.0)),
            ("after", after, delay),
        ):
            boxes = {n: BoxEstimator(experiment.landmarks, world.camera_model(n)) for n in trees}
            errors = []
            for k in range(10):
                t = 8.0 + k / 15  # every object of the scene's timeline is on the table
                truth = world.truth(t)
                camera = {
                    n: tree.camera_pose(world.joint_readings(n, t + late[n]))
                    for n, tree in trees.items()
                }
                for name in trees:
                    boxes[name].process(world.render(name, t), camera[name], t)
                for me, other in (("a", "b"), ("b", "a")):
                    poses[me] = peer_pose(boxes[me].boxes(t), boxes[other].boxes(t))
                    if poses[me] is None:
                        continue
                    p = poses[me]
                    real = ground_pose(
                        invert(truth.robots[me].matrix()) @ truth.robots[other].matrix()
                    )
                    errors.append(math.hypot(p.x - real[0], p.y - real[1]))
            for name in trees:
                worlds[name] = _seen_whole(world, truth, name, camera[name])
            won = played = 0
            for speaker, hearer in (("a", "b"), ("b", "a")):
                for _ in range(games):
                    played += 1
                    won += players[speaker].play(hearer).outcome == "success"
            out[f"peer_position_m_{label}_max"] = max(errors) if errors else math.nan
            out[f"pointing_success_{label}"] = won / played
            out[f"objects_seen_{label}"] = min(len(w) for w in worlds.values())
    return out


def _seen_whole(world: SimWorld, truth: Truth, name: str, pose: CameraPose) -> list[Located]:
    """Robot ``name``'s world model: every object it sees whole, at the ground position its
    features give from camera ``pose``; ids are ``<robot><true id>``."""
    camera = world.camera_model(name)
    out = []
    for oid, view in truth.views[name].objects.items():
        b = view.bbox
        if b is None or view.visible < 0.98 or view.pixels < 30:
            continue
        if b[0] == 0 or b[1] == 0 or b[0] + b[2] >= camera.width or b[1] + b[3] >= camera.height:
            continue
        exp = sensory_experience(b, FLAT, camera, pose)
        if exp.on_ground and exp.x is not None and exp.y is not None:
            out.append(Located(f"{name}{oid}", exp.x, exp.y))
    return out


def run_once(degrade: str, steps: tuple[int, int], fps: float, games: int) -> dict[str, object]:
    scene, _ = load_scene(find_scene(SCENE))
    profile = load_profile(find("robots", "myon"))
    tree = KinematicTree.from_settings(profile.kinematics)
    out: dict[str, object] = {"images": degrade}
    corrected: dict[str, KinematicTree] = {}
    delays: dict[str, float] = {}
    for robot in ("a", "b"):
        result, corrected[robot], figures = calibrate(robot, degrade, steps, fps)
        delays[robot] = result.delay.value
        truth = scene.robot(robot).perturb
        errors: dict[str, object] = {
            **figures,
            "pan_zero_error_deg": abs(
                math.degrees(result.joint_zero["head_pan"].value - truth.joint_zero["head_pan"])
            ),
            "pan_zero_sigma_deg": math.degrees(result.joint_zero["head_pan"].sigma),
            "delay_error_ms": abs(result.delay.value - truth.delay) * 1000,
            "delay_sigma_ms": result.delay.sigma * 1000,
            **mounting_errors(tree, result, truth.mounting(), truth.joint_zero["head_tilt"]),
            "reprojection_px_before": result.reprojection_px_before,
            "reprojection_px_after": result.reprojection_px_after,
        }
        if robot == ROBOT:
            errors.update(ground_errors(find_scene(SCENE), tree, corrected[robot], delays[robot]))
        out[robot] = {k: round(v, 3) if isinstance(v, float) else v for k, v in errors.items()}
    peers = peers_and_pointing({"a": tree, "b": tree}, corrected, delays, games)
    out.update({k: round(v, 4) for k, v in peers.items()})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", nargs=2, type=int, default=(5, 3), metavar=("PAN", "TILT"))
    parser.add_argument("--fps", type=float, default=15.0)
    parser.add_argument("--games", type=int, default=20, help="pointing games each way")
    parser.add_argument("--images", choices=["clean", "webcam", "both"], default="both")
    args = parser.parse_args()
    kinds = ["clean", "webcam"] if args.images == "both" else [args.images]
    for kind in kinds:
        print(json.dumps(run_once(kind, tuple(args.steps), args.fps, args.games)), flush=True)


if __name__ == "__main__":
    main()
