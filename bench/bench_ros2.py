"""What the ROS 2 side costs a daemon at 30 fps: the CPU of publishing every world model on
the ROS 2 topics (``[ros2]`` on, all topics, images at the default 2 a second).

A stand-in for ``rmw_zenohd`` runs in a child process (a plain Zenoh router on 127.0.0.1 with a
subscriber on every ROS 2 key of domain 0, counting samples, so that every topic is really
sent). This process then hands world models to :class:`~percept.runtime.ros2.publisher.
Ros2Publisher` at ``--fps`` for ``--seconds``, as the daemon's perception thread does, and
measures its own CPU time (all threads: the hand-over, the publisher's thread, Zenoh's) against
the same loop with the publisher off. The world models hold ``--objects`` objects on the ground,
two boxes and one peer; the image is ``--width`` x ``--height``.

    python bench/bench_ros2.py [--seconds 20] [--fps 30] [--width 640 --height 480]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import time

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.perception.landmarks.records import BoxPose
from percept.runtime.net.messages import PeerPose, World, WorldObject
from percept.runtime.ros2.publisher import Ros2Publisher
from percept.runtime.ros2.settings import Ros2Settings

ROUTER = """
import sys, threading, zenoh
port = int(sys.argv[1])
conf = zenoh.Config.from_json5(
    '{mode: "router", listen: {endpoints: ["tcp/127.0.0.1:%d"]},'
    ' scouting: {multicast: {enabled: false}}}' % port
)
session = zenoh.open(conf)
count = [0]
session.declare_subscriber("0/**", lambda s: count.__setitem__(0, count[0] + 1))
print("ready", flush=True)
sys.stdin.readline()
print(count[0], flush=True)
session.close()
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def world(frame: int, objects: int) -> World:
    a = 0.01 * frame
    R = [[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]]
    features = {
        "width": 0.05,
        "height": 0.07,
        "luminance": 0.4,
        "green_red": 0.1,
        "yellow_blue": 0.2,
    }
    return World(
        robot="a",
        stamp=time.time(),
        frame=frame,
        camera={"R": R, "t": [0.02, 0.0, 0.45]},
        objects=tuple(
            WorldObject(i, (1.0, 2.0, 3.0, 4.0), {"x": 0.3 + 0.05 * i, "y": 0.01 * i, **features})
            for i in range(objects)
        ),
        boxes=(BoxPose(1, 0.8, 0.2, 0.1, 3), BoxPose(2, 0.8, -0.2, -0.1, 3)),
        peers={"b": PeerPose(1.5, 0.0, 3.1, time.time(), 2)},
    )


def cpu() -> float:
    t = os.times()
    return t.user + t.system


def run(publisher: Ros2Publisher | None, args: argparse.Namespace, image: np.ndarray) -> float:
    """Seconds of CPU per second of the loop at ``args.fps``."""
    joints = {"head_pan": 0.1, "head_tilt": -0.4}
    period = 1.0 / args.fps
    began, cpu0 = time.monotonic(), cpu()
    frame = 0
    while time.monotonic() - began < args.seconds:
        frame += 1
        w = world(frame, args.objects)
        if publisher is not None:
            publisher.offer(w, joints, image)
        time.sleep(max(0.0, began + frame * period - time.monotonic()))
    return (cpu() - cpu0) / (time.monotonic() - began)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--objects", type=int, default=5)
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)
    args = p.parse_args()
    port = free_port()
    router = subprocess.Popen(
        [sys.executable, "-c", ROUTER, str(port)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert router.stdout is not None and router.stdin is not None
    router.stdout.readline()
    # A table-top-like picture: smooth shading, a few discs, sensor noise (pure noise would make
    # JPEG far costlier than any camera frame).
    rng = np.random.default_rng(0)
    v, u = np.mgrid[0 : args.height, 0 : args.width]
    image = np.repeat((100 + 80 * v / args.height)[..., None], 3, axis=2)
    for k in range(args.objects):
        disc = (u - args.width * (k + 1) / (args.objects + 1)) ** 2 + (v - args.height / 2) ** 2
        image[disc < (args.width / 20) ** 2] = (40 + 40 * k, 60, 200 - 30 * k)
    image = np.clip(image + rng.normal(0, 4, image.shape), 0, 255).astype(np.uint8)
    camera = CameraModel(
        np.array([[500.0, 0, args.width / 2], [0, 500.0, args.height / 2], [0, 0, 1]]),
        width=args.width,
        height=args.height,
    )
    off = run(None, args, image)
    settings = Ros2Settings(enabled=True, router=f"tcp/127.0.0.1:{port}")
    publisher = Ros2Publisher(settings, "a", camera)
    time.sleep(1.0)  # the session opened and the topics declared
    on = run(publisher, args, image)
    publisher.close()
    router.stdin.write("\n")
    router.stdin.flush()
    received = int(router.stdout.readline())
    router.wait(timeout=10)
    print(
        json.dumps(
            {
                "fps": args.fps,
                "seconds": args.seconds,
                "image": f"{args.width}x{args.height}",
                "cpu_off": round(off, 4),
                "cpu_on": round(on, 4),
                "rise_percent_of_a_core": round(100 * (on - off), 2),
                "samples_sent": dict(publisher.samples),
                "samples_received": received,
                "replaced_before_sent": publisher.dropped,
                "load_average": os.getloadavg(),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
