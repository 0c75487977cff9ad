"""Forward kinematics speed: microseconds per camera pose, median and p90.

For each shipped platform profile (inline chains) and for the full ROBOTIS OP3 URDF with its legs
(ground frame from the soles, when ../shared/data is there), time ``KinematicTree.camera_pose``
at random joint angles, one call at a time as the daemon makes them.

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

from kinematics.settings import KinematicsSettings  # noqa: E402
from kinematics.tree import KinematicTree  # noqa: E402
from runtime.profile import load_profile  # noqa: E402

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


if __name__ == "__main__":
    main()
