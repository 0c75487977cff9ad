"""The ground-plane homographies against projecting ground points through both camera poses."""

from __future__ import annotations

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.ground import view_homography
from percept.kinematics.pose import CameraPose, rpy_matrix

CAMERA = CameraModel.from_opening_angles(1.0, 0.8, 640, 480)


def _pixel(pose: CameraPose, point: np.ndarray) -> np.ndarray:
    return CAMERA.project((pose.R.T @ (point - pose.t))[None])[0]


def _apply(H: np.ndarray, uv: np.ndarray) -> np.ndarray:
    p = H @ np.r_[uv, 1.0]
    return p[:2] / p[2]


def test_view_homography_moves_ground_points_with_the_camera() -> None:
    before = CameraPose(R=rpy_matrix([0.0, 0.5, 0.0]), t=np.array([0.0, 0.0, 0.45]))
    after = CameraPose(R=rpy_matrix([0.02, 0.45, 0.15]), t=np.array([0.01, 0.03, 0.44]))
    H = view_homography(CAMERA.K, before, after)
    for point in ([0.8, 0.1, 0.0], [0.5, -0.2, 0.0], [1.4, 0.3, 0.0]):
        p = np.array(point)
        assert np.allclose(_apply(H, _pixel(before, p)), _pixel(after, p), atol=1e-6)


def test_a_turn_in_place_moves_every_pixel_exactly() -> None:
    """With the camera centre fixed a point off the ground moves by the same homography."""
    t = np.array([0.0, 0.0, 0.45])
    before = CameraPose(R=rpy_matrix([0.0, 0.4, -0.1]), t=t)
    after = CameraPose(R=rpy_matrix([0.0, 0.3, 0.2]), t=t)
    H = view_homography(CAMERA.K, before, after)
    high = np.array([1.0, 0.2, 0.3])  # 30 cm above the ground
    assert np.allclose(_apply(H, _pixel(before, high)), _pixel(after, high), atol=1e-6)
