"""Camera model, pixel <-> ray <-> ground projection, the horizon, and camera calibration."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.kinematics.camera import (
    CAMERA_FROM_CV,
    CV_FROM_CAMERA,
    CalibrationError,
    CameraModel,
    camera_to_cv,
    cv_to_camera,
    load_intrinsics,
    save_intrinsics,
)
from percept.kinematics.ground import GroundPoint, ground_point, ground_points, height_at
from percept.kinematics.pose import CameraPose, rpy_matrix
from percept.kinematics.settings import LensSettings
from percept.runtime.cli import main

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "opencv-aruco-tutorial"
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"{DATA} (public data) is absent")


def _tutorial_camera() -> CameraModel:
    return load_intrinsics(DATA / "tutorial_camera_charuco.yml")


def _pose(pitch: float, yaw: float = 0.0, roll: float = 0.0, height: float = 0.5) -> CameraPose:
    # rpy_matrix pitch > 0 turns x down: a camera looking down at the floor.
    return CameraPose(R=rpy_matrix((roll, pitch, yaw)), t=np.array([0.1, -0.05, height]))


def test_cv_frame_conversion() -> None:
    assert np.allclose(CV_FROM_CAMERA @ [1, 0, 0], [0, 0, 1])  # optical axis -> cv z
    assert np.allclose(CV_FROM_CAMERA @ [0, 1, 0], [-1, 0, 0])  # left -> -cv x (x is right)
    assert np.allclose(CV_FROM_CAMERA @ [0, 0, 1], [0, -1, 0])  # up -> -cv y (y is down)
    assert np.allclose(CAMERA_FROM_CV @ CV_FROM_CAMERA, np.eye(3))
    assert np.linalg.det(CV_FROM_CAMERA) == pytest.approx(1.0)
    p = np.random.default_rng(1).normal(size=(5, 3))
    assert np.allclose(cv_to_camera(camera_to_cv(p)), p)


def test_opening_angles_give_the_image_edges() -> None:
    cam = CameraModel.from_opening_angles(math.radians(120), math.radians(109.6), 176, 144)
    assert cam.fx == pytest.approx(88 / math.tan(math.radians(60)))
    assert (cam.cx, cam.cy) == (87.5, 71.5)
    # The outer edge of the leftmost pixel column is 60 degrees left of the optical axis.
    left_edge, top_edge = cam.pixel_rays(np.array([[-0.5, 71.5], [87.5, -0.5]]))
    assert math.degrees(math.atan2(left_edge[1], left_edge[0])) == pytest.approx(60)
    assert math.degrees(math.atan2(top_edge[2], top_edge[0])) == pytest.approx(54.8)
    assert [math.degrees(a) for a in cam.opening_angles()] == pytest.approx([120, 109.6])
    lens = LensSettings(opening_angles=(math.radians(120), math.radians(109.6)))
    assert np.allclose(CameraModel.from_lens(lens, 176, 144).K, cam.K)


@needs_data
@pytest.mark.parametrize("distorted", [False, True])
def test_pixel_ray_pixel_round_trip(distorted: bool) -> None:
    cam = _tutorial_camera()
    if not distorted:
        cam = CameraModel(K=cam.K, width=cam.width, height=cam.height)
    rng = np.random.default_rng(2)
    uv = rng.uniform([0, 0], [cam.width - 1, cam.height - 1], size=(200, 2))
    rays = cam.pixel_rays(uv)
    assert np.all(rays[:, 0] == 1.0)
    assert np.abs(cam.project(rays * rng.uniform(0.2, 5.0, size=(200, 1))) - uv).max() < 1e-6


@needs_data
@pytest.mark.parametrize("distorted", [False, True])
def test_no_pixels_have_no_rays(distorted: bool) -> None:
    """A frame with no anchor in view asks for the rays of no pixels: none, with or without
    a lens distortion (OpenCV's undistortion gives None for no points)."""
    cam = _tutorial_camera()
    if not distorted:
        cam = CameraModel(K=cam.K, width=cam.width, height=cam.height)
    assert cam.normalised(np.zeros((0, 2))).shape == (0, 2)
    assert cam.pixel_rays(np.zeros((0, 2))).shape == (0, 3)


@needs_data
@pytest.mark.parametrize("distorted", [False, True])
def test_ground_point_to_image_and_back(distorted: bool) -> None:
    cam = _tutorial_camera()
    if not distorted:
        cam = CameraModel(K=cam.K, width=cam.width, height=cam.height)
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(20):
        pose = _pose(rng.uniform(0.2, 0.9), rng.uniform(-1, 1), rng.uniform(-0.1, 0.1))
        ground = np.column_stack(
            [rng.uniform(-2, 2.5, 300), rng.uniform(-2, 2, 300), np.zeros(300)]
        )
        in_camera = (ground - pose.t) @ pose.R  # ground -> camera frame: R^T (p - t)
        uv = cam.project(in_camera)
        seen = cam.contains(uv)
        xy, valid = ground_points(pose, cam.pixel_rays(uv[seen]))
        assert valid.all()
        assert np.abs(xy - ground[seen, :2]).max() < 1e-6
        checked += int(seen.sum())
    assert checked > 500


def test_points_behind_the_camera_have_no_pixel() -> None:
    cam = CameraModel.from_opening_angles(1.0, 0.8, 320, 240)
    uv = cam.project(np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    assert np.isnan(uv[0]).all() and np.allclose(uv[1], [159.5, 119.5])


def test_horizon_is_flagged_never_nan_or_huge() -> None:
    pose = _pose(pitch=0.3)
    rays = np.array(
        [
            [1.0, 0.0, math.tan(0.3)],  # exactly horizontal in the ground frame
            [1.0, 0.0, 0.5],  # above the horizon
            [1.0, 0.0, math.tan(0.3) - 1e-4],  # a hair below: meets the ground km away
            [1.0, 0.0, -0.5],  # well below: on the ground
        ]
    )
    xy, valid = ground_points(pose, rays)
    assert valid.tolist() == [False, False, False, True]
    assert np.isfinite(xy).all() and np.abs(xy).max() < 50
    assert ground_point(pose, rays[1]) == GroundPoint(on_ground=False)
    below = ground_point(pose, rays[3])
    assert below.on_ground and below.x == pytest.approx(xy[3, 0])
    # A camera at or below the ground sees no ground point at all.
    sunk = CameraPose(R=pose.R, t=np.array([0.0, 0.0, -0.1]))
    assert not ground_points(sunk, rays)[1].any()
    with pytest.raises(ValueError):
        GroundPoint(on_ground=True)


def test_height_on_the_plane_facing_the_camera() -> None:
    pose = CameraPose(R=np.eye(3), t=np.array([0.0, 0.0, 0.5]))
    # A ray towards a point 0.3 m high, 2 m ahead and 1 m to the left.
    target = np.array([2.0, 1.0, 0.3])
    assert height_at(pose, target - pose.t, target[:2]) == pytest.approx(0.3)
    assert height_at(pose, -(target - pose.t), target[:2]) is None  # looking away
    assert height_at(pose, np.array([0.0, 0.0, -1.0]), pose.t[:2]) is None  # right below


@needs_data
def test_intrinsics_files_yaml_json_and_scaling(tmp_path: Path) -> None:
    cam = _tutorial_camera()
    assert (cam.width, cam.height) == (640, 480) and cam.dist.size == 5
    assert cam.fx == pytest.approx(452.51, abs=0.01)
    save_intrinsics(tmp_path / "c.json", cam, rms=0.2)
    again = load_intrinsics(tmp_path / "c.json")
    assert np.allclose(again.K, cam.K) and np.allclose(again.dist, cam.dist)
    assert json.loads((tmp_path / "c.json").read_text(encoding="utf-8"))["rms"] == 0.2
    half = CameraModel.from_lens(LensSettings(intrinsics=tmp_path / "c.json"), 320, 240)
    assert half.fx == pytest.approx(cam.fx / 2)
    assert half.cx == pytest.approx((cam.cx + 0.5) / 2 - 0.5)
    # The same ray through corresponding pixels of the two resolutions.
    uv = np.array([[100.0, 400.0]])
    small = (uv + 0.5) / 2 - 0.5
    assert np.allclose(half.pixel_rays(small), cam.pixel_rays(uv))
    with pytest.raises(CalibrationError, match="aspect ratio"):
        cam.scaled(640, 360)
    (tmp_path / "bad.json").write_text('{"camera_matrix": [1, 2, 3]}', encoding="utf-8")
    with pytest.raises(CalibrationError, match="3x3"):
        load_intrinsics(tmp_path / "bad.json")
    with pytest.raises(CalibrationError, match="not found"):
        load_intrinsics(tmp_path / "missing.yml")


@needs_data
@pytest.mark.timeout(60)
def test_calibrate_camera_charuco_recovers_the_tutorial_intrinsics(tmp_path: Path) -> None:
    images = [str(DATA / f"img_0{i}.jpg") for i in range(4)]
    out = tmp_path / "cam.yml"
    args = ["calibrate-camera", *images, "--board", "charuco", "--squares", "5", "7"]
    args += ["--square-size", "0.04", "--marker-size", "0.02", "--dict", "DICT_6X6_250"]
    assert main([*args, "--out", str(out)]) == 0
    ours, theirs = load_intrinsics(out), _tutorial_camera()
    for a, b in ((ours.fx, theirs.fx), (ours.fy, theirs.fy), (ours.cx, theirs.cx)):
        assert a == pytest.approx(b, rel=0.02)
    assert ours.cy == pytest.approx(theirs.cy, rel=0.03)
    fs = cv2.FileStorage(str(out), cv2.FILE_STORAGE_READ)
    assert 0 < fs.getNode("rms").real() < 0.5


def _checkerboard_views(K: np.ndarray, size: tuple[int, int], n: int) -> list[np.ndarray]:
    """Pinhole renders of a 9x6-square checkerboard (30 mm squares) from varied poses."""
    cols, rows, square, ppm = 9, 6, 0.03, 4000  # ppm: board texture pixels per metre
    board = np.full((rows * 120 + 240, cols * 120 + 240), 255, np.uint8)
    for r in range(rows):
        for c in range(cols):
            if (r + c) % 2 == 0:
                board[120 + r * 120 : 240 + r * 120, 120 + c * 120 : 240 + c * 120] = 0
    # Texture pixel (i, j) -> board point ((j - 120) / ppm, (i - 120) / ppm, 0).
    texture_to_board = np.array([[1 / ppm, 0, -120 / ppm], [0, 1 / ppm, -120 / ppm], [0, 0, 1]])
    rng = np.random.default_rng(4)
    views = []
    for _ in range(n):
        rvec = rng.uniform(-0.5, 0.5, 3)
        R, _ = cv2.Rodrigues(rvec)
        centre = np.array([cols * square / 2, rows * square / 2, 0.0])
        t = np.array([*rng.uniform(-0.05, 0.05, 2), rng.uniform(0.45, 0.7)]) - R @ centre
        H = K @ np.column_stack([R[:, 0], R[:, 1], t]) @ texture_to_board
        views.append(cv2.warpPerspective(board, H, size, borderValue=255))
    return views


@pytest.mark.timeout(60)
def test_calibrate_camera_checkerboard_on_rendered_views(tmp_path: Path) -> None:
    K = np.array([[520.0, 0, 322.0], [0, 515.0, 236.0], [0, 0, 1]])
    paths = []
    for i, view in enumerate(_checkerboard_views(K, (640, 480), 8)):
        paths.append(str(tmp_path / f"v{i}.png"))
        cv2.imwrite(paths[-1], view)
    out = tmp_path / "cam.json"
    args = ["calibrate-camera", *paths, "--board", "checkerboard", "--squares", "9", "6"]
    assert main([*args, "--square-size", "0.03", "--out", str(out)]) == 0
    cam = load_intrinsics(out)
    assert cam.fx == pytest.approx(520, rel=0.01) and cam.fy == pytest.approx(515, rel=0.01)
    assert cam.cx == pytest.approx(322, abs=3) and cam.cy == pytest.approx(236, abs=3)


def test_calibrate_camera_says_when_the_board_is_missing(tmp_path: Path, capsys) -> None:
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((120, 160), 128, np.uint8))
    args = ["calibrate-camera", str(blank), str(blank), str(blank), "--out", str(tmp_path / "o")]
    assert main(args) == 1
    assert "found in 0 image(s)" in capsys.readouterr().err
