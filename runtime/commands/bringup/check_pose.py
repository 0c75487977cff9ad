"""``percept check-pose``: is the camera where the profile says? One marker lies flat on the
floor at a measured spot; the robot looks at it, and this prints how far from that spot forward
kinematics puts the marker's centre (the ground error) and how far the camera is from where the
marker says it is (the camera-pose error).

The marker lies with its top edge away from the robot (along its ground frame's x) unless
``--marker-heading`` says otherwise; any marker of the experiment's dictionary that is not on one
of its boxes will do.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

from percept.runtime.commands.bringup._joint_angles import add_set_option, parse_angles

if TYPE_CHECKING:
    import numpy as np

    from percept.kinematics.camera import CameraModel
    from percept.kinematics.pose import CameraPose
    from percept.perception.landmarks.detection.detector import Marker

NAME = "check-pose"
HELP = "check the camera pose the profile gives against one marker on the floor"

EXIT_NOT_SEEN = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", required=True, metavar="PROFILE", help="platform profile to check")
    p.add_argument(
        "--marker-at",
        nargs=2,
        type=float,
        required=True,
        metavar=("X", "Y"),
        help="the marker's centre as measured in the robot's ground frame, metres",
    )
    p.add_argument(
        "--marker-heading",
        type=float,
        default=0.0,
        metavar="RAD",
        help="direction its top edge faces in the robot's ground frame (default 0: away)",
    )
    p.add_argument("--marker-id", type=int, help="the marker's id (default: the one not on a box)")
    p.add_argument(
        "--side", type=float, default=0.1, metavar="M", help="black square's side (default 0.1)"
    )
    p.add_argument(
        "--experiment", default="tabletop", metavar="E", help="for the dictionary and boxes"
    )
    p.add_argument("--sim", metavar="SCENE", help="look in this simulated scene")
    p.add_argument("--name", default="a", help="--sim: the robot in the scene (default a)")
    p.add_argument("--image", metavar="IMG", help="a photo from the robot's camera instead")
    add_set_option(p, "--image: a joint's reading when the photo was taken (repeatable)")
    p.add_argument("--time", type=float, default=0.0, help="--sim: scene time, seconds")
    p.add_argument("--json", action="store_true", help="print one JSON line")


def run(args: argparse.Namespace) -> int:
    import cv2

    from percept.config import find
    from percept.kinematics.camera import CameraModel
    from percept.kinematics.tree import KinematicTree
    from percept.perception.landmarks.detection.detector import MarkerDetector
    from percept.runtime.settings.experiment import load_experiment
    from percept.runtime.settings.profile import load_profile

    if (args.sim is None) == (args.image is None):
        print("percept check-pose: give --sim SCENE or --image IMG", file=sys.stderr)
        return EXIT_NOT_SEEN
    profile = load_profile(find("robots", args.robot))
    experiment = load_experiment(find("experiments", args.experiment))
    tree = KinematicTree.from_settings(profile.kinematics)
    cam = profile.camera
    lens = CameraModel.from_lens(cam.lens, cam.width, cam.height)
    if args.sim:
        from percept.runtime.settings.scene import open_world

        with open_world(args.sim) as world:
            image = world.render(args.name, args.time)
            readings = world.joint_readings(args.name, args.time + cam.joint_delay)
    else:
        photo = cv2.imread(args.image)
        if photo is None:
            print(f"percept check-pose: {args.image}: not an image", file=sys.stderr)
            return EXIT_NOT_SEEN
        image = photo
        try:
            readings = parse_angles(args.set, tree.movable_joints)
        except ValueError as err:
            print(f"percept check-pose: {err}", file=sys.stderr)
            return EXIT_NOT_SEEN
    on_boxes = {m.id for b in experiment.landmarks.boxes for m in b.markers}
    seen = [
        m
        for m in MarkerDetector.from_settings(experiment.landmarks).detect(image)
        if (m.id == args.marker_id if args.marker_id is not None else m.id not in on_boxes)
    ]
    if len(seen) != 1:
        what = "no" if not seen else f"{len(seen)}"
        print(
            f"percept check-pose: {what} floor marker seen (ids on the boxes do not count); "
            "turn the head towards it or give --marker-id",
            file=sys.stderr,
        )
        return EXIT_NOT_SEEN
    pose = tree.camera_pose(readings)
    report = check(seen[0], lens, pose, args.marker_at, args.marker_heading, args.side)
    if args.json:
        print(json.dumps(report))
    else:
        print(
            f"marker {seen[0].id}: forward kinematics puts it {report['ground_error_m'] * 100:.1f}"
            f" cm from where it lies ({report['ground_error_pct']:.1f} % of its distance); the "
            f"camera is {report['camera_position_error_m'] * 1000:.0f} mm and "
            f"{report['camera_rotation_error_deg']:.2f} deg from where the marker says"
        )
    return 0


def check(
    marker: Marker,
    lens: CameraModel,
    pose: CameraPose,
    at: tuple[float, float],
    heading: float,
    side: float,
) -> dict[str, float]:
    """Ground error of the marker's centre and the camera-pose error the marker implies."""
    import numpy as np

    from percept.kinematics.camera import CV_FROM_CAMERA
    from percept.kinematics.ground import ground_points
    from percept.kinematics.pose import transform
    from percept.perception.landmarks.pose import candidate_poses

    ray = lens.pixel_rays(_centre(marker.corners)[None, :])
    xy, valid = ground_points(pose, ray)
    truth = np.array(at, dtype=float)
    ground_error = float(np.linalg.norm(xy[0] - truth)) if valid[0] else math.inf
    # The marker's top edge along its y: ground <- marker, x right, z up.
    T_marker = transform((*at, 0.0), (0.0, 0.0, heading - math.pi / 2))
    implied = []
    for candidate in candidate_poses(marker.corners, side, lens):
        T = T_marker @ np.linalg.inv(candidate.matrix())  # ground <- OpenCV camera
        implied.append((T[:3, 3], T[:3, :3] @ CV_FROM_CAMERA))
    # Of IPPE's two poses, the one nearer the profile's (the other mirrors the marker's tilt).
    t, R = min(implied, key=lambda c: _angle(c[1].T @ pose.R))
    distance = float(np.linalg.norm(truth - pose.t[:2]))
    return {
        "ground_error_m": ground_error,
        "ground_error_pct": 100 * ground_error / distance,
        "camera_position_error_m": float(np.linalg.norm(t - pose.t)),
        "camera_rotation_error_deg": math.degrees(_angle(R.T @ pose.R)),
        "marker_distance_m": distance,
    }


def _centre(corners: np.ndarray) -> np.ndarray:
    """Where the diagonals of the marker's image cross: its centre's image (the corners' mean
    is not, under perspective)."""
    import numpy as np

    a, b, c, d = np.asarray(corners, dtype=float)
    u, v = c - a, d - b
    w = b - a
    s = (w[0] * v[1] - w[1] * v[0]) / (u[0] * v[1] - u[1] * v[0])
    return a + s * u


def _angle(R: np.ndarray) -> float:
    return math.acos(max(-1.0, min(1.0, (float(R[0, 0] + R[1, 1] + R[2, 2]) - 1.0) / 2.0)))
