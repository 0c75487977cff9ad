"""Pictures of marker-carrying boxes for a known camera pose, drawn with OpenCV.

For tests and benchmarks that need exact ground truth without the simulated world: each box
face that looks towards the camera is filled, its markers are warped onto it by their homography
(supersampled, then averaged down, so edges are anti-aliased as a real sensor's are).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from percept.kinematics.camera import CameraModel, cv_from_ground
from percept.kinematics.pose import FACE_YAW, CameraPose, ground_transform
from percept.perception.landmarks.detection.detector import load_dictionary
from percept.perception.landmarks.geometry import marker_in_box
from percept.perception.landmarks.settings import BoxSettings, LandmarkSettings


@dataclass(frozen=True)
class PlacedBox:
    """A box of the experiment at ``(x, y, theta)`` in the ground frame."""

    box: BoxSettings
    x: float
    y: float
    theta: float

    def matrix(self) -> np.ndarray:
        """The 4x4 transform ground <- box."""
        return ground_transform(self.x, self.y, self.theta)


def _face_corners(box: BoxSettings, face: str) -> np.ndarray:
    """The four corners (4, 3) of a side face in the box frame."""
    length, width, height = box.size
    yaw = FACE_YAW[face]
    normal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    right = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    depth = length / 2 if face in ("front", "back") else width / 2
    half = width / 2 if face in ("front", "back") else length / 2
    c = normal * depth
    return np.array(
        [c - right * half, c + right * half, c + right * half, c - right * half]
    ) + np.array([[0, 0, height], [0, 0, height], [0, 0, 0], [0, 0, 0]])


def render(
    settings: LandmarkSettings,
    boxes: list[PlacedBox],
    camera: CameraModel,
    camera_pose: CameraPose,
    background: int = 110,
    face_colour: tuple[int, int, int] = (150, 190, 215),
    supersample: int = 4,
) -> np.ndarray:
    """A BGR image of ``boxes`` seen by ``camera`` at ``camera_pose`` (no lens distortion)."""
    big = camera.scaled(camera.width * supersample, camera.height * supersample)
    image = np.full((big.height, big.width, 3), background, np.uint8)
    dictionary = load_dictionary(settings.dictionary, settings.dictionary_file)
    ground_to_cv = cv_from_ground(camera_pose)
    eye = np.asarray(camera_pose.t, dtype=float)
    # Painter's order: the farthest box first.
    for placed in sorted(boxes, key=lambda b: -math.hypot(b.x - eye[0], b.y - eye[1])):
        T = ground_to_cv @ placed.matrix()
        for face in FACE_YAW:
            corners = _face_corners(placed.box, face)
            centre = placed.matrix() @ np.append(corners.mean(axis=0), 1.0)
            yaw = placed.theta + FACE_YAW[face]
            if (eye[:2] - centre[:2]) @ (math.cos(yaw), math.sin(yaw)) <= 0:
                continue
            pts = (T[:3, :3] @ corners.T).T + T[:3, 3]
            if np.any(pts[:, 2] <= 0.01):
                continue
            uv = (pts[:, :2] / pts[:, 2:]) @ big.K[:2, :2].T + big.K[:2, 2]
            cv2.fillConvexPoly(
                image, np.round(uv * 16).astype(np.int32), face_colour, cv2.LINE_AA, 4
            )
            for m in placed.box.markers:
                if m.face == face:
                    _draw_marker(
                        image, dictionary, m.id, m.side, T @ marker_in_box(placed.box, m), big
                    )
    return cv2.resize(image, (camera.width, camera.height), interpolation=cv2.INTER_AREA)


def _draw_marker(image, dictionary, marker_id: int, side: float, T_cv_marker, camera) -> None:
    cells = dictionary.markerSize + 2
    px = cells * 16
    margin = px // cells
    texture = cv2.aruco.generateImageMarker(dictionary, marker_id, px)
    texture = cv2.copyMakeBorder(
        texture, margin, margin, margin, margin, cv2.BORDER_CONSTANT, value=255
    )
    # Texture pixel edges -> marker plane (x right, y up, metres); pixel centres at integers.
    scale = side / px
    A = np.array(
        [
            [scale, 0.0, (0.5 - margin) * scale - side / 2],
            [0.0, -scale, side / 2 - (0.5 - margin) * scale],
            [0.0, 0.0, 1.0],
        ]
    )
    R, t = T_cv_marker[:3, :3], T_cv_marker[:3, 3]
    H = camera.K @ np.column_stack([R[:, 0], R[:, 1], t]) @ A
    size = (image.shape[1], image.shape[0])
    warped = cv2.warpPerspective(
        cv2.cvtColor(texture, cv2.COLOR_GRAY2BGR), H, size, flags=cv2.INTER_LINEAR
    )
    mask = cv2.warpPerspective(
        np.full(texture.shape, 255, np.uint8), H, size, flags=cv2.INTER_NEAREST
    )
    image[mask > 0] = warped[mask > 0]
