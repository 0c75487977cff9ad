"""Where the perception thread's time goes: the daemon's pipeline step by step, in one process.

Robot a's camera in a simulated scene at 640x480 (MYON robots), rendered before the timing,
goes through :class:`percept.runtime.daemon.pipeline.Pipeline` as in the daemon: the marker
search on every 3rd frame (in the daemon on a thread of its own, here in turn), its markers
applied at the next frame, and every world model encoded as it is sent. ``still``:
``tabletop-myon``, the head held; ``moving``: ``tabletop-pan`` with the MYON robots, calibrated
while the head sweeps its working range (the first 6 s), measured while it pans with the objects
on the table (from 11 s). Prints the thread's CPU ms per frame of each step (``step`` is all of
``Pipeline.step``, ``perception`` the ``Perception.process`` inside it; ``markers`` the search,
``encode`` the world's encoding, both outside ``step``), how many sensory experiences kept their
last fit and how many marker searches kept their last box fit, and a hash of the world models
(the same code and frames give the same hash).

    MUJOCO_GL=egl python bench/bench_pipeline.py [--heads still,moving] [--frames 240] [--json]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from percept.perception.features.experience import SensoryMemory  # noqa: E402
from percept.perception.landmarks.boxes import BoxEstimator  # noqa: E402
from percept.perception.landmarks.detection.detector import Marker  # noqa: E402
from percept.perception.landmarks.follow import MarkerSearch  # noqa: E402
from percept.perception.pipeline import Perception  # noqa: E402
from percept.runtime.daemon.pipeline import FrameInputs, Pipeline  # noqa: E402
from percept.runtime.net.messages import encode  # noqa: E402
from percept.runtime.settings.experiment import load_experiment  # noqa: E402
from percept.runtime.settings.profile import load_profile  # noqa: E402

FPS = 30.0
EXPERIMENT = ROOT / "config" / "experiments" / "tabletop.toml"
MYON = ROOT / "config" / "robots" / "myon.toml"
# head: (scene, calibration frames, first measured frame)
HEADS = {"still": ("tabletop-myon", 60, 60), "moving": ("tabletop-pan", 180, 330)}
WARMUP = 30  # frames before the timing: the kernels loaded from numba's cache
STEPS: list[tuple[type, str, str]] = [
    (Pipeline, "step", "step"),
    (Perception, "process", "perception"),
    (SensoryMemory, "experience", "experiences"),
    (BoxEstimator, "observe", "box fit"),
    (BoxEstimator, "boxes", "box averages"),
    (MarkerSearch, "__call__", "markers"),
]


def frames(head: str, count: int) -> tuple[np.ndarray, list[dict[str, float]]]:
    """Robot a's camera images and head joints at 30 fps from the start of ``head``'s scene."""
    from percept.runtime.settings.scene import open_world

    scene, _, start = HEADS[head]
    if head == "moving":
        import tempfile

        from bench.bench_moving_head import myon_copy

        scene = myon_copy(scene, Path(tempfile.mkdtemp()))
    world = open_world(scene)
    try:
        images = np.stack([world.render("a", k / FPS) for k in range(start + count)])
        joints = [world.joint_angles("a", k / FPS) for k in range(start + count)]
    finally:
        world.close()
    return images, joints


def timers(spent: dict[str, float]) -> Callable[[], None]:
    """Wrap :data:`STEPS` so that each adds its thread CPU seconds to ``spent``; returns the
    undo."""
    originals = [(owner, name, getattr(owner, name)) for owner, name, _ in STEPS]
    for (owner, name, key), (_, _, function) in zip(STEPS, originals, strict=True):

        def timed(*args: object, _f: Callable = function, _key: str = key, **kw: object) -> object:
            began = time.thread_time()
            try:
                return _f(*args, **kw)
            finally:
                spent[_key] += time.thread_time() - began

        setattr(owner, name, timed)

    def undo() -> None:
        for owner, name, function in originals:
            setattr(owner, name, function)

    return undo


def measure(head: str, count: int) -> dict[str, object]:
    _, calibration, start = HEADS[head]
    images, joints = frames(head, count)
    height, width = images.shape[1:3]
    pipeline = Pipeline("a", load_profile(MYON), load_experiment(EXPERIMENT), width, height, 0.1)

    def inputs(k: int, marker_frames: tuple[int, ...] = ()) -> FrameInputs:
        return FrameInputs(k, k / FPS, 1.7e9 + k / FPS, joints[k], marker_frames=marker_frames)

    pipeline.calibrate(list(images[:calibration]), inputs=[inputs(k) for k in range(calibration)])
    spent: dict[str, float] = defaultdict(float)
    digest = hashlib.sha256()
    found: dict[int, list[Marker]] = {}
    undo: Callable[[], None] | None = None  # the timers, once the warm-up is over
    for k in range(start, start + count):
        if k == start + WARMUP:
            undo = timers(spent)
        out = pipeline.step(images[k], inputs(k, tuple(found)), found)
        found = {}
        if k % 3 == 0 and out.pose is not None:
            found[k] = pipeline.boxes.search(images[k], out.pose.pose)
        if out.world is not None:
            began = time.thread_time()
            payload = encode(out.world)
            if k >= start + WARMUP:
                spent["encode"] += time.thread_time() - began
            digest.update(payload)
    if undo is not None:
        undo()
    timed = count - WARMUP
    row: dict[str, object] = {"head": head, "size": f"{width}x{height}", "frames": timed}
    for _, _, key in STEPS:
        row[f"{key}_ms"] = round(1000 * spent[key] / timed, 3)
    row["encode_ms"] = round(1000 * spent["encode"] / timed, 3)
    row["experiences_kept"] = pipeline.features.reused
    row["box_fits_kept"] = pipeline.boxes.refits_saved
    row["worlds_sha256"] = digest.hexdigest()[:16]
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--heads", default="still,moving", help="comma-separated, of: still, moving")
    p.add_argument("--frames", type=int, default=240, help="frames per head, 30 of them warm-up")
    p.add_argument("--json", action="store_true", help="one JSON line per head")
    args = p.parse_args()
    os.environ.setdefault("MUJOCO_GL", "egl")
    if args.frames <= WARMUP:
        p.error(f"--frames must be more than the {WARMUP} warm-up frames")
    print(f"load average {os.getloadavg()[0]:.1f}; CPU ms per frame of the thread")
    for head in [h.strip() for h in args.heads.split(",") if h.strip()]:
        if head not in HEADS:
            p.error(f"unknown head {head!r}; known: {', '.join(HEADS)}")
        row = measure(head, args.frames)
        if args.json:
            print(json.dumps(row), flush=True)
            continue
        steps = ", ".join(
            f"{key} {row[f'{key}_ms']:.2f}" for key in [*(s[2] for s in STEPS), "encode"]
        )
        print(f"{head:7} {row['size']}: {steps}", flush=True)
        print(
            f"        experiences kept {row['experiences_kept']}, box fits kept "
            f"{row['box_fits_kept']}, worlds {row['worlds_sha256']}",
            flush=True,
        )


if __name__ == "__main__":
    main()
