"""Accuracy of the sensory experiences against the simulated world's ground truth (issue 5).

Random scenes: two robots (profiles of the experiment, OP3s by default) 0.8-1.4 m from the middle
of a floor, 60-150 degrees apart, heads panning and tilting all the time; six objects (blocks,
cuboids, cylinders, cones, balls, toys; 3-15 cm) scattered so that each is 0.3-2 m from each robot.
For every frame and robot, every object that is wholly in the image and not occluded is taken with
its true bounding box and pixel count (the simulator's segmentation) and the colour histograms of
its pixels; the camera pose comes from percept's forward kinematics at the frame's joint angles.
Every feature model (``percept.perception.features.experience.FeatureSettings.model``) is measured
on the same views.

Errors against the truth: ground position (footprint centre) relative to the robot's distance,
width (the footprint's extent across the line of sight), height (the object's top); the Fig. 5.5
measure is the mean over the seven features of |scaled A - scaled B| for objects both robots see in
the same frame, with both positions expressed in robot a's frame; it is also given for the true
position and size (with the measured colour), which shows how much the objects themselves look
different from the two sides, and its width and height terms by shape. The scaling statistics
are those of this run's ``--model`` features (``--stats-out`` writes them, and ``--jsonl`` the
features for ``percept stats``).

    MUJOCO_GL=egl python bench/feature_accuracy.py [--trials 6] [--frames 30]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cv2
import numpy as np

from percept.drivers.sim.scene import JointMotion, Scene, SimObject, SimRobot
from percept.drivers.sim.world import SimWorld
from percept.kinematics.tree import KinematicTree
from percept.perception.features.experience import (
    FEATURES,
    FeatureSettings,
    SensoryExperience,
    sensory_experience,
)
from percept.perception.features.scaling import FeatureScaling
from percept.runtime.record.scorecard import true_width
from percept.runtime.settings.profile import load_profile

REPO = Path(__file__).resolve().parents[1]
SHAPES = ("block", "cuboid", "cylinder", "cone", "ball", "toy")
MODELS = ("solid", "cylinder", "chapter")


def random_object(rng: np.random.Generator, oid: int, xy: np.ndarray) -> SimObject:
    shape = SHAPES[oid % len(SHAPES)]
    if shape == "block":
        s = rng.uniform(0.03, 0.10)
        size = (s, s, s * rng.uniform(0.8, 1.5))
    elif shape == "cuboid":
        size = (rng.uniform(0.04, 0.15), rng.uniform(0.03, 0.10), rng.uniform(0.03, 0.12))
    elif shape == "cylinder":
        d = rng.uniform(0.04, 0.09)
        size = (d, d, rng.uniform(0.04, 0.14))
    elif shape == "cone":
        d = rng.uniform(0.05, 0.10)
        size = (d, d, rng.uniform(0.05, 0.12))
    elif shape == "ball":
        d = rng.uniform(0.04, 0.10)
        size = (d, d, d)
    else:
        size = (rng.uniform(0.05, 0.08), rng.uniform(0.06, 0.09), rng.uniform(0.07, 0.12))
    hue = rng.uniform(0, 180)
    hsv = np.uint8([[[hue, rng.uniform(120, 255), rng.uniform(120, 240)]]])
    color = tuple(int(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0])
    pose = (float(xy[0]), float(xy[1]), float(rng.uniform(-math.pi, math.pi)))
    return SimObject(id=oid + 1, shape=shape, size=size, color=color, pose=pose)


def random_scene(rng: np.random.Generator, profiles: list[Path], trial: int) -> Scene:
    robots, places = [], []
    angle = rng.uniform(-math.pi, math.pi)
    for i, profile in enumerate(profiles):
        if i:
            angle += rng.uniform(math.radians(60), math.radians(150))
        reach = rng.uniform(0.8, 1.4)
        xy = reach * np.array([math.cos(angle), math.sin(angle)])
        places.append(xy)
        joints = {
            "head_pan": JointMotion(
                amplitude=0.5, period=rng.uniform(5, 8), phase=rng.uniform(0, 6)
            ),
            "head_tilt": JointMotion(
                offset=-0.55, amplitude=0.2, period=rng.uniform(3, 5), phase=rng.uniform(0, 6)
            ),
        }
        robots.append(
            SimRobot(
                name="ab"[i],
                profile=profile,
                pose=(float(xy[0]), float(xy[1]), angle + math.pi),
                joints=joints,
            )
        )
    objects: list[SimObject] = []
    while len(objects) < 6:
        xy = rng.uniform(-0.6, 0.6, 2)
        if np.linalg.norm(xy) > 0.6:
            continue
        if any(np.linalg.norm(xy - o.pose[:2]) < 0.18 for o in objects):
            continue
        if not all(0.3 <= np.linalg.norm(xy - p) <= 2.0 for p in places):
            continue
        objects.append(random_object(rng, len(objects), xy))
    return Scene(name=f"features-{trial}", robots=tuple(robots), seed=trial, objects=tuple(objects))


def histograms(image: np.ndarray, mask: np.ndarray, bins: int = 16) -> np.ndarray:
    ycrcb = cv2.cvtColor(image, cv2.COLOR_BGR2YCrCb)
    m = mask.astype(np.uint8)
    h = np.vstack([cv2.calcHist([ycrcb], [c], m, [bins], [0, 256]).ravel() for c in range(3)])
    return h / h.sum(axis=1, keepdims=True)


def truth_width(obj, sight: np.ndarray, heading: float) -> float:
    """Extent of the object's footprint across the line of sight (``sight``: unit, in the ground
    frame of a robot whose heading in the world is ``heading``)."""
    c, s = math.cos(heading), math.sin(heading)
    turn = np.array([[c, s], [-s, c]]) @ obj.R[:2, :2]  # object frame -> robot's ground frame
    return true_width(obj.shape, obj.size, turn, np.array([-sight[1], sight[0]]))


def to_frame(pose: tuple[float, float, float], xy: np.ndarray) -> np.ndarray:
    """World point ``xy`` in the ground frame of a robot standing at ``pose``."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    d = xy - (x, y)
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def from_frame(pose: tuple[float, float, float], xy: np.ndarray) -> np.ndarray:
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([x + c * xy[0] - s * xy[1], y + s * xy[0] + c * xy[1]])


def run(args: argparse.Namespace) -> dict:
    profiles = [Path(p).resolve() for p in args.profiles]
    platforms = {"ab"[i]: load_profile(p) for i, p in enumerate(profiles)}
    trees = {name: KinematicTree.from_settings(p.kinematics) for name, p in platforms.items()}
    rng = np.random.default_rng(args.seed)
    rows: list[dict] = []
    fk_error = 0.0
    feature_time = defaultdict(float)
    for trial in range(args.trials):
        scene = random_scene(rng, profiles, trial)
        with SimWorld(scene, platforms) as world:
            for k in range(args.frames):
                t = 0.2 + k * args.dt
                truth = world.truth(t)
                for name in world.robots:
                    cam = world.camera_model(name)
                    robot = truth.robots[name]
                    pose = trees[name].camera_pose(robot.joints)
                    fk_error = max(fk_error, float(np.abs(pose.t - robot.camera.t).max()))
                    fk_error = max(fk_error, float(np.abs(pose.R - robot.camera.R).max()))
                    image = world.render(name, t, effects=False)
                    labels = world.labels(name, t)
                    for oid, view in truth.views[name].objects.items():
                        b = view.bbox
                        if b is None or view.visible < 0.98 or view.pixels < 30:
                            continue
                        if b[0] == 0 or b[1] == 0:
                            continue
                        if b[0] + b[2] >= cam.width or b[1] + b[3] >= cam.height:
                            continue
                        obj = truth.objects[oid]
                        hist = histograms(image, labels == oid)
                        centre = to_frame(robot.pose, obj.position[:2])
                        sight = centre - pose.t[:2]
                        distance = float(np.linalg.norm(centre))
                        sight /= np.linalg.norm(sight)
                        row = {
                            "trial": trial,
                            "t": t,
                            "robot": name,
                            "pose": robot.pose,
                            "object": (trial, oid),
                            "shape": obj.shape,
                            "distance": distance,
                            "truth": (centre, truth_width(obj, sight, robot.pose[2]), obj.top),
                        }
                        for model in MODELS:
                            t0 = time.perf_counter()
                            exp = sensory_experience(
                                b, hist, cam, pose, FeatureSettings(model=model), pixels=view.pixels
                            )
                            feature_time[model] += time.perf_counter() - t0
                            row[model] = exp
                        rows.append(row)
    return {"rows": rows, "fk_error": fk_error, "feature_time": feature_time}


def experience(row: dict, source: str) -> SensoryExperience:
    """A row's features from ``source`` (a model, or ``truth``: the true position, width and
    height with the measured colour, to show how much the objects themselves differ between the
    two viewpoints)."""
    if source != "truth":
        return row[source]
    (x, y), width, height = row["truth"]
    colour = row[MODELS[0]]
    return replace(colour, x=float(x), y=float(y), width=width, height=height)


def summarise(result: dict, args: argparse.Namespace) -> None:
    rows = [r for r in result["rows"] if all(r[m].on_ground for m in MODELS)]
    print(f"{len(rows)} object views, {args.trials} scenes x {args.frames} frames x 2 robots")
    print(f"FK vs simulator camera pose: max difference {result['fk_error']:.2e}")
    for model in MODELS:
        per_view = result["feature_time"][model] / len(result["rows"]) * 1e6
        print(f"  {model}: {per_view:.0f} us per object")
    table: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for r in rows:
        centre, width, height = r["truth"]
        for model in MODELS:
            e = r[model]
            for group in (r["shape"], "all"):
                cell = table[(model, group)]
                cell["position"].append(
                    math.hypot(e.x - centre[0], e.y - centre[1]) / r["distance"]
                )
                cell["width"].append(e.width / width - 1)
                cell["height"].append(e.height / height - 1)
    print("median |error| (position: % of distance; width, height: % of truth; signed median)")
    print(
        f"  {'model':10} {'shape':9} {'n':>5} {'position':>9} {'width':>7} {'height':>7}"
        f" {'(width':>7} {'height)':>7}"
    )
    for model in MODELS:
        for group in (*SHAPES, "all"):
            cell = table.get((model, group))
            if not cell:
                continue
            med = {k: 100 * float(np.median(np.abs(v))) for k, v in cell.items()}
            bias = {k: 100 * float(np.median(v)) for k, v in cell.items()}
            n = len(cell["position"])
            print(
                f"  {model:10} {group:9} {n:5d} {med['position']:8.2f}% {med['width']:6.1f}%"
                f" {med['height']:6.1f}% {bias['width']:+6.1f}% {bias['height']:+6.1f}%"
            )
    # One scaling for all (the statistics of this run's --model features), as in an experiment.
    scaling = FeatureScaling.measure(r[args.model].features() for r in rows)
    if args.stats_out:
        scaling.save(args.stats_out, "From bench/feature_accuracy.py, simulated scenes.")
    pairs: dict = defaultdict(dict)
    for r in rows:
        pairs[(r["object"], r["t"])][r["robot"]] = r
    both = [views for views in pairs.values() if len(views) == 2]
    for source in (*MODELS, "truth"):
        diffs, per_feature = [], defaultdict(list)
        per_shape: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
        for views in both:
            a, b = (experience(views[name], source) for name in "ab")
            sa, sb = scaling.scale(a), scaling.scale(b)
            # b's position in a's frame, through the true robot poses.
            world_xy = from_frame(views["b"]["pose"], np.array([b.x, b.y]))
            bx, by = to_frame(views["a"]["pose"], world_xy)
            sb["x"], sb["y"] = (scaling.stats["x"].scale(bx), scaling.stats["y"].scale(by))
            d = [abs(sa[f] - sb[f]) for f in FEATURES]
            diffs.append(float(np.mean(d)))
            for f, v in zip(FEATURES, d, strict=True):
                per_feature[f].append(v)
                per_shape[views["a"]["shape"]][f].append(v)
        detail = ", ".join(f"{f} {np.mean(v):.3f}" for f, v in per_feature.items())
        print(
            f"Fig. 5.5 measure ({source}): mean |scaled A - scaled B| = {np.mean(diffs):.4f} over "
            f"{len(diffs)} objects seen by both in the same frame ({detail})"
        )
        # The spatial terms by shape, and each shape's share of the measure's sum of terms.
        shapes = ", ".join(
            f"{shape} {np.mean(cell['width']):.3f}/{np.mean(cell['height']):.3f}"
            f" ({len(cell['width'])}, {np.sum(cell['width']) + np.sum(cell['height']):.1f})"
            for shape, cell in ((s, per_shape[s]) for s in SHAPES if s in per_shape)
        )
        print(f"  width/height terms by shape (pairs, summed width + height): {shapes}")
    if args.jsonl:
        with open(args.jsonl, "w", encoding="utf-8") as fh:
            for r in rows:
                fh.write(json.dumps({"features": r[args.model].features()}) + "\n")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default = REPO / "config" / "robots" / "robotis-op3.toml"
    p.add_argument("--profiles", nargs=2, default=[default, default], metavar="TOML")
    p.add_argument("--trials", type=int, default=6)
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--dt", type=float, default=0.25, help="seconds between frames")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--model", choices=MODELS, default=MODELS[0], help="for --stats-out/--jsonl")
    p.add_argument("--stats-out", help="write this run's feature statistics (TOML)")
    p.add_argument("--jsonl", help="write this run's features as JSON lines")
    args = p.parse_args()
    t0 = time.perf_counter()
    result = run(args)
    summarise(result, args)
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
