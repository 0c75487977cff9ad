"""``percept markers``: find markers in images; with intrinsics and a side length, their poses."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from percept.kinematics.camera import CameraModel

NAME = "markers"
HELP = "detect markers (ids, corners; poses with --camera and --marker-size) in images"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("images", nargs="+", metavar="IMAGE", help="image files")
    p.add_argument("--camera", metavar="INTRINSICS", help="OpenCV YAML or JSON intrinsics")
    p.add_argument(
        "--dict", default="DICT_APRILTAG_36h11", metavar="NAME", help="cv2.aruco dictionary"
    )
    p.add_argument(
        "--dict-file", metavar="YML", help="custom dictionary (nmarkers, markersize, marker_i)"
    )
    p.add_argument("--marker-size", type=float, metavar="METRES", help="black square's side")
    p.add_argument(
        "--detector",
        default="percept",
        choices=["percept", "aruco", "apriltag"],
        help="percept: cv2.aruco's quads, read by percept, corners fitted to the edges "
        "(default); aruco: cv2.aruco's search with --refinement; apriltag: the AprilTag C "
        "library (pupil-apriltags), AprilTag dictionaries only",
    )
    p.add_argument(
        "--refinement",
        default="edges",
        choices=["none", "subpix", "contour", "apriltag", "edges"],
        help="--detector aruco's corner refinement (default edges: lines fitted to the edges; "
        "apriltag: AprilTag's corners in a window round each marker; none gives OpenCV's "
        "integer corners)",
    )
    p.add_argument(
        "--decimation",
        type=int,
        default=2,
        choices=[1, 2, 3, 4],
        help="--detector apriltag: quad search on 1/n of the pixels (default 2)",
    )
    p.add_argument(
        "--threshold",
        default="adaptive",
        choices=["adaptive", "otsu"],
        help="otsu: the chapter's global threshold from the luminance histogram first",
    )
    p.add_argument("--json", action="store_true", help="one JSON line per image")


def _camera(path: str, width: int, height: int) -> CameraModel:
    """Intrinsics for images of ``width`` x ``height``; a file without an image size (as
    OpenCV's tutorial files) is taken to be for this size."""
    import cv2
    import numpy as np

    from percept.kinematics.camera import CalibrationError, CameraModel, load_intrinsics

    try:
        return load_intrinsics(path).scaled(width, height)
    except CalibrationError as err:
        if "image_width" not in str(err) or Path(path).suffix.lower() == ".json":
            raise
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
    K, dist = fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat()
    fs.release()
    dist = np.zeros(0) if dist is None else np.asarray(dist, dtype=float).reshape(-1)
    return CameraModel(K=np.asarray(K, dtype=float), dist=dist, width=width, height=height)


def run(args: argparse.Namespace) -> int:
    import cv2

    from percept.drivers.camera.image_file import ImageFileError, read_image
    from percept.kinematics.camera import CalibrationError
    from percept.perception.landmarks.detection.detector import LandmarkError, MarkerDetector
    from percept.perception.landmarks.pose import candidate_poses, refine

    want_pose = args.camera is not None and args.marker_size is not None
    if (args.camera is None) != (args.marker_size is None):
        print("percept markers: poses need both --camera and --marker-size", file=sys.stderr)
        return 2
    try:
        detector = MarkerDetector(
            args.dict,
            Path(args.dict_file) if args.dict_file else None,
            args.threshold,
            args.refinement,
            args.detector,
            args.decimation,
        )
    except LandmarkError as err:
        print(f"percept markers: {err}", file=sys.stderr)
        return 2
    failed = 0
    for path in args.images:
        try:
            image = read_image(path, cv2.IMREAD_GRAYSCALE)
        except ImageFileError as err:  # reported, and the other images are still read
            failed += 1
            if args.json:
                print(json.dumps({"image": path, "error": str(err)}), flush=True)
            else:
                print(err, flush=True)
            continue
        camera = None
        if want_pose:
            try:
                camera = _camera(args.camera, image.shape[1], image.shape[0])
            except CalibrationError as err:
                print(f"percept markers: {err}", file=sys.stderr)
                return 2
        out = []
        for m in detector.detect(image):
            entry: dict[str, object] = {"id": m.id, "corners": m.corners.round(3).tolist()}
            if camera is not None:
                best = candidate_poses(m.corners, args.marker_size, camera)[0]
                entry["pose"] = refine(best, m.corners, args.marker_size, camera, "lm").as_dict()
            out.append(entry)
        if args.json:
            print(json.dumps({"image": path, "markers": out}), flush=True)
        else:
            ids = " ".join(str(e["id"]) for e in out) or "-"
            print(f"{path}: {len(out)} markers: {ids}", flush=True)
    return 1 if failed else 0
