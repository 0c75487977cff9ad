"""``percept calibrate-camera``: camera intrinsics and distortion from photos of a board.

Print a ChArUco board (robust to partial views; preferred) or a checkerboard, take 10-20 photos of
it with the robot's camera at its working resolution from different angles and distances, filling
the image's corners too, and run this. The output is an OpenCV YAML (or JSON) file to name in a
platform profile's ``[camera.lens] intrinsics``.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import cv2
    import numpy as np

NAME = "calibrate-camera"
HELP = "compute camera intrinsics and distortion from photos of a ChArUco board or checkerboard"

log = logging.getLogger("percept.calibrate")

# At least this many corners in a view before it is used (6 fix a homography comfortably).
_MIN_CORNERS = 6


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("images", nargs="+", metavar="IMAGE", help="photos of the board")
    p.add_argument("--board", choices=["charuco", "checkerboard"], default="charuco")
    p.add_argument(
        "--squares",
        nargs=2,
        type=int,
        default=(5, 7),
        metavar=("X", "Y"),
        help="squares across and down the board (default 5 7)",
    )
    p.add_argument(
        "--square-size", type=float, default=0.04, metavar="M", help="square side, metres"
    )
    p.add_argument(
        "--marker-size",
        type=float,
        default=0.02,
        metavar="M",
        help="ChArUco marker side, metres (default 0.02)",
    )
    p.add_argument(
        "--dict", default="DICT_6X6_250", metavar="NAME", help="ArUco dictionary of the ChArUco"
    )
    p.add_argument(
        "--legacy",
        action="store_true",
        help="ChArUco board printed by OpenCV < 4.6 with an even number of rows",
    )
    p.add_argument("--out", required=True, metavar="FILE", help="output .yml or .json")


def _charuco_detector(
    args: argparse.Namespace,
) -> tuple[cv2.aruco.CharucoBoard, cv2.aruco.CharucoDetector]:
    import cv2

    name = args.dict.upper()
    if not name.startswith("DICT_"):
        name = "DICT_" + name
    if not hasattr(cv2.aruco, name):
        raise ValueError(f"unknown ArUco dictionary {args.dict!r}")
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
    board = cv2.aruco.CharucoBoard(
        tuple(args.squares), args.square_size, args.marker_size, dictionary
    )
    board.setLegacyPattern(args.legacy)
    return board, cv2.aruco.CharucoDetector(board)


def _views(
    args: argparse.Namespace, images: list[tuple[str, np.ndarray]]
) -> tuple[list[np.ndarray], list[np.ndarray], list[str]]:
    """Object points and image points of every usable view; the names of the unusable ones."""
    import cv2
    import numpy as np

    objects, pixels, skipped = [], [], []
    if args.board == "charuco":
        board, detector = _charuco_detector(args)
    else:
        inner = (args.squares[0] - 1, args.squares[1] - 1)
        grid = np.zeros((inner[0] * inner[1], 3), np.float32)
        grid[:, :2] = np.mgrid[0 : inner[0], 0 : inner[1]].T.reshape(-1, 2) * args.square_size
    for name, gray in images:
        if args.board == "charuco":
            corners, ids, _, _ = detector.detectBoard(gray)
            if ids is None or len(ids) < _MIN_CORNERS:
                skipped.append(name)
                continue
            # OpenCV's stubs type detectedCorners (an InputArrayOfArrays) as a sequence of
            # arrays only; a ChArUco board takes the one array of corners detectBoard gives.
            obj, img = board.matchImagePoints(corners, ids)  # type: ignore[call-overload]
        else:
            found, corners = cv2.findChessboardCorners(gray, inner)
            if not found:
                skipped.append(name)
                continue
            criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
            img = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), criteria)
            obj = grid
        objects.append(np.asarray(obj, np.float32).reshape(-1, 3))
        pixels.append(np.asarray(img, np.float32).reshape(-1, 2))
        log.info("%s: %d corners", name, len(objects[-1]))
    return objects, pixels, skipped


def run(args: argparse.Namespace) -> int:
    import cv2
    import numpy as np

    from percept.drivers.camera.image_file import ImageFileError, read_image
    from percept.kinematics.camera import CameraModel, save_intrinsics

    images = []
    for path in args.images:
        try:
            images.append((path, read_image(path, cv2.IMREAD_GRAYSCALE)))
        except ImageFileError as err:  # reported; the other images may still calibrate
            print(f"percept calibrate-camera: skipped: {err}", file=sys.stderr)
    if not images:
        print("percept calibrate-camera: none of the images could be read", file=sys.stderr)
        return 2
    sizes = {g.shape for _, g in images}
    if len(sizes) != 1:
        print(f"percept calibrate-camera: images differ in size: {sorted(sizes)}", file=sys.stderr)
        return 2
    height, width = sizes.pop()
    try:
        objects, pixels, skipped = _views(args, images)
    except ValueError as err:
        print(f"percept calibrate-camera: {err}", file=sys.stderr)
        return 2
    for name in skipped:
        log.warning("%s: board not found, view left out", name)
    if len(objects) < 3:
        print(
            f"percept calibrate-camera: the board was found in {len(objects)} image(s); "
            "need at least 3 (better 10-20 from varied angles)",
            file=sys.stderr,
        )
        return 1
    rms, K, dist, _, _ = cv2.calibrateCamera(objects, pixels, (width, height), None, None)
    camera = CameraModel(K=K, dist=np.asarray(dist).reshape(-1), width=width, height=height)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    save_intrinsics(args.out, camera, rms=float(rms), views=len(objects))
    hfov, vfov = (np.degrees(a) for a in camera.opening_angles())
    print(
        f"{len(objects)} views, rms reprojection error {rms:.3f} px: "
        f"fx={camera.fx:.1f} fy={camera.fy:.1f} cx={camera.cx:.1f} cy={camera.cy:.1f}, "
        f"opening angles {hfov:.1f} x {vfov:.1f} deg -> {args.out}"
    )
    return 0
