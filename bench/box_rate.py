"""Box messages per second as an outside subscriber sees them (issue 6 target: 5.0 +/- 0.25 Hz).

A child process plays robot ``a``: a :class:`percept.runtime.net.link.Link` on a free local port and
a :class:`percept.runtime.net.peers.BoxPublisher` at the experiment's ``box_rate``; with ``--load``
a second thread in that process runs marker detection and box estimation on a rendered 640x480 image
as fast as it can (a busy perception loop competing for the interpreter). This process is the
outsider: a plain zenoh session (not percept's Link) that connects to the child's endpoint and
timestamps each sample on arrival.

    python bench/box_rate.py [--seconds 30] [--load]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from tests.support.zenoh_rig import free_port

REPO = Path(__file__).resolve().parents[1]


def _busy_perception(stop: threading.Event, counter: list[int]) -> None:
    """Marker detection and box estimation in a loop, on a rendered 640x480 view of a box."""
    from percept.kinematics.camera import CameraModel
    from percept.kinematics.pose import CameraPose, rpy_matrix
    from percept.perception.evaluation.markers import PlacedBox, render
    from percept.perception.landmarks.boxes import BoxEstimator
    from percept.perception.landmarks.settings import BoxSettings, LandmarkSettings, MarkerSettings

    faces = ("front", "left", "back", "right")
    box = BoxSettings(
        1, (0.18, 0.18, 0.18), tuple(MarkerSettings(i, 0.1, f) for i, f in enumerate(faces))
    )
    settings = LandmarkSettings(boxes=(box,))
    camera = CameraModel.from_opening_angles(1.0472, 0.8172, 640, 480)
    pose = CameraPose(rpy_matrix((0.0, 0.5, 0.0)), np.array([0.0, 0.0, 0.45]))
    image = render(settings, [PlacedBox(box, 0.7, 0.05, 2.6)], camera, pose)
    estimator = BoxEstimator(settings, camera)
    while not stop.is_set():
        estimator.process(image, pose, time.monotonic())
        counter[0] += 1


def publisher(endpoint: str, load: bool) -> None:
    """The child: robot a publishing its boxes until stdin closes."""
    from percept.perception.landmarks.records import BoxPose
    from percept.runtime.net.link import Link
    from percept.runtime.net.peers import BoxPublisher
    from percept.runtime.settings.experiment import Experiment, RobotEntry, load_experiment

    shipped = load_experiment(REPO / "config/experiments/tabletop.toml")
    robots = (RobotEntry("a", shipped.robot("a").profile, endpoint),)
    experiment = Experiment(name="bench", robots=robots, peers=shipped.peers)
    boxes = [BoxPose(1, 0.8, 0.1, 3.0, 2), BoxPose(2, 0.6, 0.4, 1.5, 1)]
    stop = threading.Event()
    frames = [0]
    if load:
        threading.Thread(target=_busy_perception, args=(stop, frames), daemon=True).start()
    with Link(experiment, "a") as link:
        sender = BoxPublisher(link, "a", lambda: boxes, experiment.peers.box_rate).start()
        print("ready", flush=True)
        began = time.monotonic()
        sys.stdin.read()
        stop.set()
        sender.stop()
        elapsed = time.monotonic() - began
    print(json.dumps({"sent": sender.sent, "perception_fps": frames[0] / elapsed}), flush=True)


def measure(seconds: float, load: bool) -> dict:
    import zenoh

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    child = subprocess.Popen(
        [sys.executable, __file__, "--publisher", endpoint, *(["--load"] if load else [])],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        encoding="utf-8",
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    arrivals: list[float] = []
    try:
        assert child.stdout is not None and child.stdout.readline().strip() == "ready"
        config = zenoh.Config.from_json5(
            json.dumps(
                {
                    "mode": "peer",
                    "connect": {"endpoints": [endpoint]},
                    "scouting": {"multicast": {"enabled": False}},
                }
            )
        )
        with zenoh.open(config) as session:
            session.declare_subscriber(
                "percept/a/boxes", lambda _sample: arrivals.append(time.monotonic())
            )
            time.sleep(1.0)  # let the subscription settle, then count from the next sample
            start = len(arrivals)
            time.sleep(seconds)
            times = np.array(arrivals[start:])
        child.stdin.close()  # type: ignore[union-attr]
        stats = json.loads(child.stdout.readline())
    finally:
        child.kill()
        child.wait()
    intervals = np.diff(times)
    windows = []
    for t in np.arange(times[0], times[-1] - 5.0 + 1e-9, 5.0):
        inside = times[(times >= t) & (times < t + 5.0)]
        windows.append((inside.size - 1) / (inside[-1] - inside[0]))
    return {
        "seconds": seconds,
        "load": load,
        "perception_fps": stats["perception_fps"],
        "messages": int(times.size),
        "rate_hz": (times.size - 1) / (times[-1] - times[0]),
        "rate_5s_windows_hz": [float(w) for w in windows],
        "interval_ms": {
            "median": float(np.median(intervals) * 1000),
            "p90": float(np.percentile(intervals, 90) * 1000),
            "min": float(intervals.min() * 1000),
            "max": float(intervals.max() * 1000),
        },
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--seconds", type=float, default=30.0, help="how long to listen")
    p.add_argument("--load", action="store_true", help="busy perception in the robot process")
    p.add_argument("--publisher", metavar="ENDPOINT", help=argparse.SUPPRESS)
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    args = p.parse_args()
    if args.publisher:
        publisher(args.publisher, args.load)
        return
    r = measure(args.seconds, args.load)
    if args.json:
        print(json.dumps(r, indent=2))
        return
    i = r["interval_ms"]
    windows = r["rate_5s_windows_hz"]
    print(
        f"{r['messages']} box messages in {r['seconds']:g} s: {r['rate_hz']:.3f} Hz "
        f"(5 s windows {min(windows):.2f}-{max(windows):.2f} Hz); interval median "
        f"{i['median']:.1f} ms, p90 {i['p90']:.1f}, min {i['min']:.1f}, max {i['max']:.1f}"
    )
    if r["load"]:
        print(f"perception loop in the robot process: {r['perception_fps']:.1f} frames/s")
    ok = math.isclose(r["rate_hz"], 5.0, abs_tol=0.25)
    print("within 5.0 +/- 0.25 Hz" if ok else "OUTSIDE 5.0 +/- 0.25 Hz")


if __name__ == "__main__":
    main()
