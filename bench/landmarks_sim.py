"""Box poses, peer poses and the pointing game in the simulated world (issue 6 targets).

Random scenes around the tabletop experiment's two landmark boxes (18 cm cartons with a 10 cm
AprilTag on each side, ``config/experiments/tabletop.toml``): each trial puts the boxes at random
headings near the back of the table, five small objects (4-7 cm) at least ``--spacing`` apart in
front of them, and two ROBOTIS OP3s (320x200 camera, pixel noise 1/255) 0.8-1.0 m from the
middle, 90-140 degrees apart, heads slowly panning. Per frame and robot:

- markers are detected in the rendered image and box poses estimated with the camera pose from
  percept's forward kinematics at the frame's joint angles (the estimator's output, averaged over
  its window, is compared with the true box pose in the robot's frame);
- after ``--frames`` frames, each robot's estimate of the other's pose (SPEC §4.7 from the shared
  boxes) is compared with the truth;
- each robot's world model is the ground position of every object it sees whole (its true
  bounding box from the simulator's segmentation, turned into features by
  ``percept.perception.features.experience.sensory_experience``); then ``--games`` pointing games
  are played each way between two real Zenoh sessions on 127.0.0.1
  (``percept.runtime.games.pointing.PointingGames``).

    MUJOCO_GL=egl python bench/landmarks_sim.py [--trials 12] [--frames 10] [--games 20]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import random
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from percept.drivers.sim.scene import (
    CameraEffects,
    JointMotion,
    Scene,
    SimBox,
    SimMarker,
    SimObject,
    SimRobot,
)
from percept.drivers.sim.world import SimWorld
from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import wrap
from percept.kinematics.tree import KinematicTree
from percept.perception.features.experience import sensory_experience
from percept.perception.landmarks.boxes import BoxEstimator
from percept.perception.landmarks.records import box_error
from percept.runtime.games.monitor import same_objects
from percept.runtime.games.pointing import Located, PointingGames
from percept.runtime.net.link import Link
from percept.runtime.net.messages import PeerPose
from percept.runtime.net.peers import peer_pose, to_my_frame
from percept.runtime.settings.experiment import Experiment, RobotEntry, load_experiment
from percept.runtime.settings.profile import load_profile
from tests.support.zenoh_rig import free_port

REPO = Path(__file__).resolve().parents[1]
SHAPES = ("block", "cylinder", "cone", "ball", "toy")
CENTRE = np.array([0.05, 0.05])  # middle of the table top
FLAT = np.full((3, 16), 1 / 16)  # colour does not matter here


def _to_frame(pose: tuple[float, float, float], xy: np.ndarray) -> np.ndarray:
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    d = np.asarray(xy, dtype=float) - (x, y)
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def _in_view(robot: SimRobot, lens: CameraModel, tree: KinematicTree, xyz: np.ndarray) -> bool:
    """Whether the world point ``xyz`` shows at least 20 px inside ``robot``'s image at t = 0."""
    local = np.append(_to_frame(robot.pose, xyz[:2]), xyz[2])
    pose = tree.camera_pose(robot.angles(0.0))
    uv = lens.project(pose.R.T @ (local - pose.t))[0]
    return (
        bool(np.all(np.isfinite(uv)))
        and 20 <= uv[0] <= lens.width - 20
        and (20 <= uv[1] <= lens.height - 20)
    )


def random_scene(
    rng: random.Random, experiment: Experiment, setup: dict, spacing: float, trial: int
) -> Scene:
    """A scene as an experimenter sets one up for joint attention: both robots have every
    object in view (by its centre and top; occlusion is left to chance)."""
    boxes = []
    for box, anchor in zip(experiment.landmarks.boxes, [(0.25, 0.32), (-0.08, 0.42)], strict=False):
        markers = tuple(SimMarker(m.id, m.side, m.face, m.offset, m.roll) for m in box.markers)
        pose = (anchor[0] + rng.uniform(-0.05, 0.05), anchor[1] + rng.uniform(-0.03, 0.03))
        boxes.append(SimBox(box.id, box.size, markers, (*pose, rng.uniform(-math.pi, math.pi))))
    robots = []
    bearing = math.pi + rng.uniform(-0.35, 0.35)
    aim = CENTRE + np.array([0.0, 0.12])
    for i, name in enumerate("ab"):
        if i:
            bearing += math.radians(rng.uniform(90, 140))  # round to the -y side
        reach = rng.uniform(0.8, 1.0)
        xy = aim + reach * np.array([math.cos(bearing), math.sin(bearing)])
        heading = math.atan2(*(aim - xy)[::-1]) + rng.uniform(-0.1, 0.1)
        joints = {
            "head_tilt": JointMotion(offset=-0.5),
            "head_pan": JointMotion(
                amplitude=0.08, period=rng.uniform(3, 5), phase=rng.uniform(0, 6)
            ),
        }
        profile = experiment.robot(name).profile
        robots.append(SimRobot(name, profile, (float(xy[0]), float(xy[1]), heading), joints))
    objects: list[SimObject] = []
    for _attempt in range(5000):
        if len(objects) == 5:
            break
        xy = CENTRE + np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.22, 0.1)])
        if any(math.dist(xy, o.pose[:2]) < spacing for o in objects):
            continue
        if any(math.dist(xy, b.pose[:2]) < 0.2 for b in boxes):
            continue
        shape = SHAPES[len(objects)]
        d = rng.uniform(0.04, 0.07)
        size = (d, d, d) if shape in ("ball", "toy") else (d, d, rng.uniform(0.05, 0.09))
        if not all(
            _in_view(r, *setup[r.name], np.array([*xy, z])) for r in robots for z in (0, size[2])
        ):
            continue
        colour = tuple(rng.randrange(30, 230) for _ in range(3))
        objects.append(
            SimObject(len(objects) + 1, shape, size, colour, (*map(float, xy), rng.uniform(0, 3)))
        )
    else:
        return random_scene(rng, experiment, setup, spacing, trial)  # no room: set up again
    return Scene(
        name=f"landmarks-{trial}",
        robots=tuple(robots),
        seed=trial,
        camera=CameraEffects(noise=1.0),
        objects=tuple(objects),
        boxes=tuple(boxes),
    )


def seen_objects(world: SimWorld, truth, name: str, tree: KinematicTree) -> list[Located]:
    """What robot ``name`` has in its world model: every object it sees whole, at the ground
    position its features give; ids are ``<robot><true id>``."""
    camera = world.camera_model(name)
    pose = tree.camera_pose(truth.robots[name].joints)
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


def _stats(values: list[float]) -> dict[str, float]:
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return {"n": 0}
    return {
        "n": int(v.size),
        "median": float(np.median(v)),
        "p90": float(np.percentile(v, 90)),
        "max": float(v.max()),
    }


def pointing_players(
    links: dict[str, Link],
    worlds: dict[str, list[Located]],
    poses: dict[str, PeerPose | None],
    experiment: Experiment,
    seed: str,
) -> dict[str, PointingGames]:
    """Pointing players on ``links`` (robot name -> its link) that see ``worlds[name]`` and
    take ``poses[name]`` as their peer's pose (both read when a game asks, so the caller fills
    them as its scene runs); once built, the sessions are given half a second to meet."""
    players = {
        name: PointingGames(
            link,
            lambda n=name: worlds[n],
            lambda _peer, n=name: poses[n],
            experiment.peers,
            random.Random(f"{seed}-{name}"),
        )
        for name, link in links.items()
    }
    time.sleep(0.5)  # let the sessions' subscriptions meet
    return players


def run(args: argparse.Namespace) -> dict:
    experiment = load_experiment(args.experiment)
    landmarks = experiment.landmarks
    search = {"detector": args.detector, "corner_refinement": args.refinement}
    landmarks = dataclasses.replace(landmarks, **{k: v for k, v in search.items() if v})
    if args.box_fit:
        landmarks = dataclasses.replace(landmarks, box_fit=args.box_fit)
    experiment = dataclasses.replace(experiment, landmarks=landmarks)
    platforms = {r.name: load_profile(r.profile) for r in experiment.robots}
    trees = {n: KinematicTree.from_settings(p.kinematics) for n, p in platforms.items()}
    setup = {
        n: (CameraModel.from_lens(p.camera.lens, p.camera.width, p.camera.height), trees[n])
        for n, p in platforms.items()
    }
    rng = random.Random(args.seed)
    box_pos, box_head, peer_pos, peer_head = [], [], [], []
    no_pose = 0
    games = {
        "played": 0,
        "won": 0,
        "joint": 0,
        "won_joint": 0,
        "topic_seen": 0,
        "won_topic_seen": 0,
    }
    joint_trials = 0
    reasons: dict[str, int] = {}
    render_s = estimate_s = 0.0
    local = Experiment(
        name="bench",
        robots=tuple(
            RobotEntry(n, experiment.robot(n).profile, f"tcp/127.0.0.1:{free_port()}") for n in "ab"
        ),
        peers=dataclasses.replace(
            experiment.peers,
            answer_timeout=5.0,
            pointing_gate=args.gate or experiment.peers.pointing_gate,
        ),
    )
    worlds: dict[str, list[Located]] = {"a": [], "b": []}
    poses: dict[str, PeerPose | None] = {"a": None, "b": None}
    with Link(local, "a") as link_a, Link(local, "b") as link_b:
        players = pointing_players({"a": link_a, "b": link_b}, worlds, poses, local, str(args.seed))
        for trial in range(args.trials):
            scene = random_scene(rng, experiment, setup, args.spacing, trial)
            with SimWorld(scene, platforms) as world:
                estimators = {
                    n: BoxEstimator(experiment.landmarks, world.camera_model(n)) for n in "ab"
                }
                for k in range(args.frames):
                    t = 0.5 + k / 30
                    truth = world.truth(t)
                    for name in "ab":
                        t0 = time.perf_counter()
                        image = world.render(name, t)
                        t1 = time.perf_counter()
                        camera_pose = trees[name].camera_pose(truth.robots[name].joints)
                        estimators[name].process(image, camera_pose, t)
                        estimate_s += time.perf_counter() - t1
                        render_s += t1 - t0
                        record = truth.record(name)
                        real = {b["id"]: b["ground"] for b in record["boxes"]}
                        for b in estimators[name].boxes(t):
                            e = box_error(b, *real[b.id])
                            box_pos.append(e[0])
                            box_head.append(e[1])
                for me, other in (("a", "b"), ("b", "a")):
                    poses[me] = peer_pose(estimators[me].boxes(t), estimators[other].boxes(t))
                    real = next(r for r in truth.record(me)["robots"] if r["name"] == other)
                    if poses[me] is None:
                        no_pose += 1
                        continue
                    p = poses[me]
                    peer_pos.append(math.hypot(p.x - real["ground"][0], p.y - real["ground"][1]))
                    peer_head.append(abs(wrap(p.theta - real["ground"][2])))
                for name in "ab":
                    worlds[name] = seen_objects(world, truth, name, trees[name])
            # What the joint-attention monitor would decide: same objects, matched through a's
            # estimate of b's pose.
            carried = (
                [Located(o.id, *to_my_frame(poses["a"], o.x, o.y)) for o in worlds["b"]]
                if poses["a"] is not None
                else []
            )
            joint = same_objects(worlds["a"], carried, experiment.peers.attention_gate) is not None
            joint_trials += joint
            for speaker, hearer in (("a", "b"), ("b", "a")):
                for _ in range(args.games):
                    result = players[speaker].play(hearer)
                    games["played"] += 1
                    won = result.outcome == "success"
                    games["won"] += won
                    games["joint"] += joint
                    games["won_joint"] += won and joint
                    if not won:
                        reasons[result.reason] = reasons.get(result.reason, 0) + 1
                    if result.topic is not None and any(
                        o.id[1:] == str(result.topic)[1:] for o in worlds[hearer]
                    ):
                        games["topic_seen"] += 1
                        games["won_topic_seen"] += won
    frames = args.trials * args.frames * 2
    box_ok = [p < 0.02 and h < math.radians(2) for p, h in zip(box_pos, box_head, strict=True)]
    peer_ok = [p < 0.03 and h < math.radians(3) for p, h in zip(peer_pos, peer_head, strict=True)]
    return {
        "box_within_2cm_2deg": sum(box_ok) / max(len(box_ok), 1),
        "peer_within_3cm_3deg": sum(peer_ok) / max(len(peer_ok), 1),
        "box_position_m": _stats(box_pos),
        "box_heading_deg": _stats(np.degrees(box_head).tolist()),
        "peer_position_m": _stats(peer_pos),
        "peer_heading_deg": _stats(np.degrees(peer_head).tolist()),
        "peer_pose_missing": no_pose,
        "games": games,
        "joint_attention_trials": joint_trials,
        "failures": reasons,
        "render_ms_per_frame": 1000 * render_s / frames,
        "landmarks_ms_per_frame": 1000 * estimate_s / frames,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--experiment", default=str(REPO / "config/experiments/tabletop.toml"))
    p.add_argument("--trials", type=int, default=12)
    p.add_argument("--frames", type=int, default=10, help="frames per trial (30 fps)")
    p.add_argument("--games", type=int, default=20, help="pointing games each way per trial")
    p.add_argument("--spacing", type=float, default=0.10, help="least distance between objects")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument(
        "--box-fit", choices=["ground", "average"], help="override the experiment's box_fit"
    )
    p.add_argument("--gate", type=float, help="override the experiment's pointing gate (m)")
    p.add_argument(
        "--detector",
        choices=["percept", "aruco", "apriltag"],
        help="override the experiment's marker detector",
    )
    p.add_argument(
        "--refinement",
        choices=["none", "subpix", "contour", "apriltag", "edges"],
        help="override the experiment's corner refinement",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    args = p.parse_args()
    result = run(args)
    if args.json:
        print(json.dumps(result, indent=2))
        return
    for key in ("box_position_m", "box_heading_deg", "peer_position_m", "peer_heading_deg"):
        s = result[key]
        if s["n"]:
            scale = 100 if key.endswith("_m") else 1
            unit = "cm" if key.endswith("_m") else "deg"
            print(
                f"{key[:-2] if key.endswith('_m') else key[:-4]:14} n={s['n']:5d}  median "
                f"{s['median'] * scale:6.2f} {unit}  p90 {s['p90'] * scale:6.2f}  "
                f"max {s['max'] * scale:6.2f}"
            )
    print(
        f"box poses within 2 cm and 2 deg: {100 * result['box_within_2cm_2deg']:.1f}%; peer "
        f"poses within 3 cm and 3 deg: {100 * result['peer_within_3cm_3deg']:.1f}%; peer pose "
        f"missing (no shared box): {result['peer_pose_missing']}"
    )
    g = result["games"]
    print(
        f"pointing games: {g['won']}/{g['played']} won "
        f"({100 * g['won'] / max(g['played'], 1):.1f}%)"
        f"; topic seen by the hearer: {g['won_topic_seen']}/{g['topic_seen']} "
        f"({100 * g['won_topic_seen'] / max(g['topic_seen'], 1):.1f}%)"
    )
    print(
        f"under joint attention ({result['joint_attention_trials']}/{args.trials} trials): "
        f"{g['won_joint']}/{g['joint']} won ({100 * g['won_joint'] / max(g['joint'], 1):.1f}%)"
    )
    if result["failures"]:
        print("failures:", result["failures"])
    print(
        f"render {result['render_ms_per_frame']:.1f} ms/frame, markers and boxes "
        f"{result['landmarks_ms_per_frame']:.1f} ms/frame"
    )


if __name__ == "__main__":
    main()
