"""Speed of the simulated world on one core: ms per frame (median and p90) for rendering a robot's
camera, for the same with camera noise and flicker, and for the ground truth of that view.

    MUJOCO_GL=egl python bench/bench_sim.py [--scene tabletop-busy] [--frames 300]

The process is pinned to one CPU before MuJoCo starts (Mesa's software rasteriser would
otherwise spread over every core). The robot's camera is set to each resolution with the
profile's opening angles; frames are spread over the scene's timeline so objects move, appear
and disappear as in a real run. Besides wall-clock time, the CPU time of the whole process is
measured: on a shared machine it is the fairer figure. "x realtime" is how many 30 fps streams
(with noise) one core renders, from CPU time.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from dataclasses import replace

import numpy as np

RESOLUTIONS = ((176, 144), (320, 200), (640, 480))


def _stats(samples: list[float]) -> tuple[float, float]:
    ms = np.asarray(samples) * 1000
    return float(statistics.median(ms)), float(np.percentile(ms, 90))


def _timed(fn, wall: list[float], cpu: list[float]) -> None:
    began, began_cpu = time.perf_counter(), time.process_time()
    fn()
    wall.append(time.perf_counter() - began)
    cpu.append(time.process_time() - began_cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="tabletop-busy")
    parser.add_argument("--robot", default="a")
    parser.add_argument("--frames", type=int, default=300)
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    os.environ.setdefault("LP_NUM_THREADS", "1")

    from percept.drivers.sim.world import SimWorld
    from percept.runtime.settings.scene import find_scene, load_scene

    scene, platforms = load_scene(find_scene(args.scene))
    times = np.linspace(0.0, scene.duration, args.frames, endpoint=False)
    print(f"scene {scene.name}, robot {args.robot}, {args.frames} frames, one core")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print("ms per frame: wall-clock median / p90, and CPU time (all threads) median")
    head = ("render", "render+noise", "truth")
    print(f"{'resolution':>10}  " + "  ".join(f"{h:>20}" for h in head) + f"  {'x realtime':>10}")
    for width, height in RESOLUTIONS:
        profile = platforms[args.robot]
        camera = replace(profile.camera, width=width, height=height)
        sized = {**platforms, args.robot: replace(profile, camera=camera)}
        with SimWorld(scene, sized) as world:
            world.render(args.robot, 0.0)  # the first render opens the GL context
            world.truth(0.0, [args.robot])
            runs = {h: ([], []) for h in head}
            for t in times:
                t = float(t)
                _timed(lambda t=t: world.render(args.robot, t + 1e-4, False), *runs["render"])
                _timed(lambda t=t: world.render(args.robot, t), *runs["render+noise"])
                _timed(lambda t=t: world.truth(t, [args.robot]), *runs["truth"])
        cells = []
        for h in head:
            wall, cpu = runs[h]
            median, p90 = _stats(wall)
            cells.append(f"{median:6.2f} {p90:6.2f} {_stats(cpu)[0]:6.2f}")
        realtime = 1000 / 30 / _stats(runs["render+noise"][1])[0]
        print(
            f"{width:>4}x{height:<5}  "
            + "  ".join(f"{c:>20}" for c in cells)
            + f"  {realtime:10.1f}"
        )


if __name__ == "__main__":
    main()
