"""Forward kinematics and sensory-experience speed: microseconds per call, median and p90.

For each shipped platform profile (inline chains) and for the full ROBOTIS OP3 URDF with its legs
(ground frame from the soles, when ../shared/data is there), time ``KinematicTree.camera_pose``
at random joint angles, one call at a time as the daemon makes them. Then time
``sensory_experience`` for an object 0.3-2 m in front of the OP3, with either feature model.

    python bench/bench_kinematics.py [--calls 20000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from percept.kinematics.camera import CameraModel  # noqa: E402
from percept.kinematics.settings import KinematicsSettings  # noqa: E402
from percept.kinematics.tree import KinematicTree  # noqa: E402
from percept.perception.features.experience import FeatureSettings, sensory_experience  # noqa: E402
from percept.runtime.settings.profile import load_profile  # noqa: E402

OP3_URDF = REPO.parent / "shared" / "data" / "robots" / "robotis-op3" / "robotis_op3.urdf"


def trees() -> dict[str, KinematicTree]:
    out = {
        path.stem: KinematicTree.from_settings(load_profile(path).kinematics)
        for path in sorted((REPO / "config" / "robots").glob("*.toml"))
    }
    if OP3_URDF.is_file():
        settings = KinematicsSettings(
            camera_link="cam_gazebo_link",
            root_link="body_link",
            urdf=OP3_URDF,
            sole_links=("l_ank_roll_link", "r_ank_roll_link"),
            sole_offset=(0.024, 0.0, -0.0305),
        )
        out["op3-urdf-with-legs"] = KinematicTree.from_settings(settings)
    return out


def time_poses(
    tree: KinematicTree, calls: int, rng: np.random.Generator, moving: list[str]
) -> np.ndarray:
    names = [n for n in tree.movable_joints if n in moving]
    configs = [dict(zip(names, rng.uniform(-1, 1, len(names)), strict=True)) for _ in range(calls)]
    times = np.empty(calls)
    clock = time.perf_counter
    for i, angles in enumerate(configs):
        t0 = clock()
        tree.camera_pose(angles)
        times[i] = clock() - t0
    return times * 1e6


def time_features(calls: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    profile = load_profile(REPO / "config" / "robots" / "robotis-op3.toml")
    tree = KinematicTree.from_settings(profile.kinematics)
    cam = CameraModel.from_lens(profile.camera.lens, profile.camera.width, profile.camera.height)
    flat = np.full((3, 16), 1 / 16)
    cases = []
    while len(cases) < calls:
        pose = tree.camera_pose({"head_tilt": rng.uniform(-0.9, -0.3)})
        x, y = rng.uniform(0.3, 2.0), rng.uniform(-0.3, 0.3)
        size = rng.uniform(0.04, 0.12)
        corners = np.array(
            [
                [x + a * size, y + b * size, c * size]
                for a in (-0.5, 0.5)
                for b in (-0.5, 0.5)
                for c in (0, 1)
            ]
        )
        uv = cam.project((corners - pose.t) @ pose.R)
        if np.isfinite(uv).all() and cam.contains(uv).all():
            lo, hi = np.floor(uv.min(0)), np.ceil(uv.max(0))
            cases.append(((lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1]), pose))
    out = {}
    for model in ("cylinder", "chapter"):
        settings = FeatureSettings(model=model)
        times = np.empty(calls)
        for i, (bbox, pose) in enumerate(cases):
            t0 = time.perf_counter()
            sensory_experience(bbox, flat, cam, pose, settings)
            times[i] = time.perf_counter() - t0
        out[model] = times * 1e6
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--calls", type=int, default=20000)
    args = p.parse_args()
    rng = np.random.default_rng(0)
    print(f"{'tree':30} {'moving':>6} {'median us':>10} {'p90 us':>8}")
    for name, tree in trees().items():
        cases = {name: tree.camera_joints}
        if tree.settings.sole_links:  # legs moving, and standing still with the head moving
            cases[name + ", legs still"] = ("head_pan", "head_tilt")
        for case, moving in cases.items():
            us = time_poses(tree, args.calls, rng, list(moving))
            print(f"{case:30} {len(moving):6d} {np.median(us):10.1f} {np.percentile(us, 90):8.1f}")
    print(f"\n{'sensory_experience, OP3':30} {'model':>8} {'median us':>8} {'p90 us':>8}")
    for model, us in time_features(args.calls // 10, rng).items():
        print(f"{'':30} {model:>8} {np.median(us):8.1f} {np.percentile(us, 90):8.1f}")


if __name__ == "__main__":
    main()
