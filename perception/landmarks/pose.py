"""The pose of one marker from its four corners: IPPE_SQUARE, the planar ambiguity, refinement.

A square seen in perspective fits two poses (mirror images about the line of sight); near a
frontal view they reproject almost equally well. Markers here sit upright on box faces, so of the
two the one whose normal is near horizontal in the ground frame and faces the camera is the
marker; when both pass, the caller's previous estimate decides.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from percept.kinematics.camera import CAMERA_FROM_CV, CameraModel, cv_from_ground
from percept.kinematics.least_squares import levenberg_marquardt
from percept.kinematics.pose import CameraPose
from percept.perception.landmarks.geometry import marker_object_points

# (object points, image points, K, distortion, rvec, tvec) -> refined (rvec, tvec)
_Refiner = Callable[
    [np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray, np.ndarray],
    tuple[np.ndarray, np.ndarray],
]
_REFINERS: dict[str, _Refiner] = {
    "lm": cv2.solvePnPRefineLM,
    "vvs": cv2.solvePnPRefineVVS,
}


@dataclass(frozen=True)
class MarkerPose:
    """A marker's pose in OpenCV's camera frame (``X_cv = R(rvec) X_marker + tvec``, metres)
    and the RMS distance in pixels between its corners and their reprojection."""

    rvec: np.ndarray
    tvec: np.ndarray
    error: float

    def matrix(self) -> np.ndarray:
        """The 4x4 transform OpenCV camera <- marker."""
        T = np.eye(4)
        T[:3, :3] = cv2.Rodrigues(self.rvec)[0]
        T[:3, 3] = self.tvec
        return T

    def as_dict(self) -> dict[str, object]:
        """JSON-able: ``rvec``, ``tvec`` (OpenCV camera frame) and ``error`` (pixels)."""
        return {
            "rvec": [float(v) for v in self.rvec],
            "tvec": [float(v) for v in self.tvec],
            "error": float(self.error),
            "frame": "opencv_camera",
        }


def _rms(corners: np.ndarray, obj: np.ndarray, rvec, tvec, camera: CameraModel) -> float:
    proj, _ = cv2.projectPoints(obj, rvec, tvec, camera.K, camera.dist)
    return float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - corners) ** 2, axis=1))))


def candidate_poses(corners: np.ndarray, side: float, camera: CameraModel) -> list[MarkerPose]:
    """Both poses that IPPE_SQUARE fits to ``corners`` (4, 2), best reprojection first."""
    obj = marker_object_points(side)
    img = np.asarray(corners, dtype=float).reshape(4, 1, 2)
    n, rvecs, tvecs, _ = cv2.solvePnPGeneric(
        obj, img, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE
    )
    poses = []
    for rvec, tvec in zip(rvecs[:n], tvecs[:n], strict=True):
        r, t = rvec.reshape(3), tvec.reshape(3)
        poses.append(MarkerPose(r, t, _rms(corners, obj, r, t, camera)))
    return sorted(poses, key=lambda p: p.error)


def refine(
    pose: MarkerPose, corners: np.ndarray, side: float, camera: CameraModel, method: str
) -> MarkerPose:
    """``pose`` refined by Levenberg-Marquardt (``lm``) or virtual visual servoing (``vvs``)
    on the four corners; ``none`` returns it unchanged."""
    if method == "none":
        return pose
    obj = marker_object_points(side)
    img = np.asarray(corners, dtype=float).reshape(4, 1, 2)
    rvec, tvec = pose.rvec.reshape(3, 1).copy(), pose.tvec.reshape(3, 1).copy()
    rvec, tvec = _REFINERS[method](obj, img, camera.K, camera.dist, rvec, tvec)
    r, t = rvec.reshape(3), tvec.reshape(3)
    return MarkerPose(r, t, _rms(corners, obj, r, t, camera))


def marker_in_ground(pose: MarkerPose, camera_pose: CameraPose) -> np.ndarray:
    """The 4x4 transform ground <- marker, through the camera's pose in the ground frame."""
    T_ground_cv = np.eye(4)
    T_ground_cv[:3, :3] = camera_pose.R @ CAMERA_FROM_CV
    T_ground_cv[:3, 3] = camera_pose.t
    return T_ground_cv @ pose.matrix()


def upright_and_facing(T_ground_marker: np.ndarray, camera_pose: CameraPose, max_tilt: float):
    """Whether a marker pose fits a marker on a vertical face seen from the camera: its normal
    within ``max_tilt`` radians of horizontal and pointing towards the camera."""
    normal = T_ground_marker[:3, 2]
    tilt = math.asin(min(1.0, abs(float(normal[2]))))
    towards_camera = float(normal @ (np.asarray(camera_pose.t) - T_ground_marker[:3, 3]))
    return tilt <= max_tilt and towards_camera > 0.0


def fit_box_on_ground(
    corners: np.ndarray,
    points: np.ndarray,
    camera: CameraModel,
    camera_pose: CameraPose,
    start: tuple[float, float, float],
) -> tuple[tuple[float, float, float], float]:
    """The box pose ``(x, y, theta)`` on the ground that best reprojects its markers' corners.

    ``points`` (N, 3) are marker corners in the box frame and ``corners`` (N, 2) their pixels.
    The box stands on the ground plane and the camera pose is known, so three numbers are left
    to fit instead of six per marker: the weakly seen tilt of a small square cannot leak into the
    heading. Returns the pose and the RMS reprojection error in pixels.
    """
    rvec, tvec = _view(camera_pose)
    points = np.asarray(points, dtype=float)
    observed = np.asarray(corners, dtype=float).reshape(-1, 2)

    def residuals(rows: np.ndarray) -> np.ndarray:
        # The box at every pose of ``rows`` projected in one call (each point on its own).
        ground = np.concatenate([placed(points, p) for p in rows])
        proj, _ = cv2.projectPoints(ground, rvec, tvec, camera.K, camera.dist)
        return (proj.reshape(len(rows), -1, 2) - observed).reshape(len(rows), -1)

    best, fun = levenberg_marquardt(residuals, np.asarray(start, dtype=float))
    rms = float(np.sqrt(np.mean(fun.reshape(-1, 2) ** 2) * 2))
    x, y, theta = (float(v) for v in best)
    return (x, y, math.atan2(math.sin(theta), math.cos(theta))), rms


def project_ground(points: np.ndarray, camera: CameraModel, camera_pose: CameraPose) -> np.ndarray:
    """The pixels (N, 2) of ground-frame ``points`` (N, 3) seen by ``camera`` at ``camera_pose``."""
    rvec, tvec = _view(camera_pose)
    proj, _ = cv2.projectPoints(points, rvec, tvec, camera.K, camera.dist)
    return proj.reshape(-1, 2)


def _view(camera_pose: CameraPose) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's ``rvec``, ``tvec`` of the camera at ``camera_pose``: ground to its frame."""
    T = cv_from_ground(camera_pose)
    return cv2.Rodrigues(T[:3, :3])[0], T[:3, 3]


def placed(points: np.ndarray, pose: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """``points`` (N, 3) of a box frame in the ground frame, the box at ``pose`` (x, y, theta)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    ground = points @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
    ground[:, 0] += pose[0]
    ground[:, 1] += pose[1]
    return ground
