"""The camera model: intrinsics, lens distortion, pixel rays and projection.

Two camera frames meet here. The chapter's (and percept's) camera frame has x along the optical
axis, y left, z up (SPEC §3); OpenCV's has x right, y down, z forward. :data:`CV_FROM_CAMERA` and
:data:`CAMERA_FROM_CV` are the one conversion between them; every other module uses these.

Pixel coordinates are OpenCV's: u right, v down, the centre of the top-left pixel at (0, 0), so an
image of width w spans u in [-0.5, w - 0.5] and its centre is at u = (w - 1) / 2.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from percept.kinematics.pose import CameraPose
from percept.kinematics.settings import LensSettings


def grid_shape(width: int, height: int, step: int) -> tuple[int, int]:
    """(rows, columns) of the grid of every ``step``-th pixel of every ``step``-th row of a
    ``width`` x ``height`` image (grid pixel j is image pixel j step): what perception works on
    at large sizes, and the shape of a JPEG decoded at 1/step scale."""
    return -(-height // step), -(-width // step)


#: Maps a vector of the chapter's camera frame (x forward, y left, z up) into OpenCV's camera
#: frame (x right, y down, z forward).
CV_FROM_CAMERA = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
#: Maps a vector of OpenCV's camera frame into the chapter's camera frame.
CAMERA_FROM_CV = CV_FROM_CAMERA.T.copy()

# Iterative undistortion: enough iterations to invert strong radial terms to far below a pixel.
_UNDISTORT_CRITERIA = (3, 100, 1e-12)  # cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS


class CalibrationError(ValueError):
    """An intrinsics file that cannot be used for this camera."""


def camera_to_cv(points: np.ndarray) -> np.ndarray:
    """Points or vectors (N, 3) of the chapter's camera frame in OpenCV's camera frame."""
    return np.asarray(points, dtype=float) @ CV_FROM_CAMERA.T


def cv_to_camera(points: np.ndarray) -> np.ndarray:
    """Points or vectors (N, 3) of OpenCV's camera frame in the chapter's camera frame."""
    return np.asarray(points, dtype=float) @ CAMERA_FROM_CV.T


def cv_from_ground(pose: CameraPose) -> np.ndarray:
    """The 4x4 transform OpenCV camera <- ground of a camera at ``pose``."""
    R = CV_FROM_CAMERA @ pose.R.T
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, -R @ np.asarray(pose.t, dtype=float)
    return T


@dataclass(frozen=True)
class CameraModel:
    """A pinhole camera with OpenCV's lens distortion (``dist`` may be empty: no distortion).

    ``K`` is OpenCV's camera matrix ``[[f_x, 0, c_x], [0, f_y, c_y], [0, 0, 1]]`` for an image
    of ``width`` x ``height`` pixels.
    """

    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(0))
    width: int = 0
    height: int = 0

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    @property
    def distorted(self) -> bool:
        # The array's own method: np.any's dispatch costs twice as much, asked every frame.
        return bool(self.dist.any())

    @classmethod
    def from_opening_angles(
        cls, horizontal: float, vertical: float, width: int, height: int
    ) -> CameraModel:
        """An ideal pinhole whose image spans the opening angles (radians); centred, no skew."""
        fx = (width / 2) / math.tan(horizontal / 2)
        fy = (height / 2) / math.tan(vertical / 2)
        K = np.array([[fx, 0.0, (width - 1) / 2], [0.0, fy, (height - 1) / 2], [0.0, 0.0, 1.0]])
        return cls(K=K, width=width, height=height)

    @classmethod
    def from_lens(cls, lens: LensSettings, width: int, height: int) -> CameraModel:
        """From a profile's ``[camera.lens]``: its calibration file if given, else its opening
        angles. A file calibrated at another resolution of the same aspect ratio is scaled."""
        if lens.intrinsics is not None:
            return load_intrinsics(lens.intrinsics).scaled(width, height)
        return cls.from_opening_angles(*lens.opening_angles, width, height)

    def scaled(self, width: int, height: int) -> CameraModel:
        """The same lens at another image size of the same aspect ratio."""
        if (width, height) == (self.width, self.height):
            return self
        sx, sy = width / self.width, height / self.height
        if abs(sx / sy - 1.0) > 0.01:
            raise CalibrationError(
                f"intrinsics are for {self.width}x{self.height}, the camera delivers "
                f"{width}x{height}: a different aspect ratio needs its own calibration"
            )
        K = self.K.copy()
        K[0, 0], K[1, 1], K[0, 1] = K[0, 0] * sx, K[1, 1] * sy, K[0, 1] * sx
        # Scale about the top-left pixel's outer corner, which stays at (-0.5, -0.5).
        K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
        K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
        return CameraModel(K=K, dist=self.dist.copy(), width=width, height=height)

    def opening_angles(self) -> tuple[float, float]:
        """Horizontal and vertical opening angle of the undistorted pinhole, radians."""
        return (
            2 * math.atan((self.width / 2) / self.fx),
            2 * math.atan((self.height / 2) / self.fy),
        )

    def normalised(self, uv: np.ndarray) -> np.ndarray:
        """Undistorted normalised image coordinates (N, 2) ``((u - c_x)/f_x, (v - c_y)/f_y)``
        of pixels ``uv`` (N, 2), in OpenCV's convention."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        if not self.distorted:
            return (uv - (self.cx, self.cy)) / (self.fx, self.fy)
        if len(uv) == 0:  # (OpenCV's undistortPoints returns None for no points)
            return np.zeros((0, 2))
        import cv2

        xy = cv2.undistortPoints(
            uv.reshape(-1, 1, 2), self.K, self.dist, criteria=_UNDISTORT_CRITERIA
        ).reshape(-1, 2)
        if self.dist.size > 8:
            return xy
        # OpenCV's fixed-point iteration stalls near the corners of strongly distorted lenses;
        # a few Newton steps on distort(xy) = observed make the ray exact.
        observed = (uv - (self.cx, self.cy)) / (self.fx, self.fy)
        hx, hy = np.array([1e-7, 0.0]), np.array([0.0, 1e-7])
        for _ in range(3):
            # The point and its four neighbours distorted in one call (asked per anchor per
            # frame: five calls cost five times the numpy calls, for a handful of points).
            around = np.stack([xy, xy + hx, xy - hx, xy + hy, xy - hy]).reshape(-1, 2)
            d = _distort(around, self.dist).reshape(5, -1, 2)
            residual = d[0] - observed
            jx = (d[1] - d[2]) / 2e-7
            jy = (d[3] - d[4]) / 2e-7
            det = jx[:, 0] * jy[:, 1] - jy[:, 0] * jx[:, 1]
            step_x = (jy[:, 1] * residual[:, 0] - jy[:, 0] * residual[:, 1]) / det
            step_y = (jx[:, 0] * residual[:, 1] - jx[:, 1] * residual[:, 0]) / det
            xy = xy - np.column_stack([step_x, step_y])
        return xy

    def pixel_rays(self, uv: np.ndarray) -> np.ndarray:
        """Rays (N, 3) through pixels ``uv`` (N, 2) in the chapter's camera frame, as
        ``(1, -(u - c_x)/f_x, -(v - c_y)/f_y)`` after undistortion (not unit length)."""
        n = self.normalised(uv)
        rays = np.empty((len(n), 3))
        rays[:, 0], rays[:, 1:] = 1.0, -n
        return rays

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of points (N, 3) given in the chapter's camera frame, with distortion.

        A point not in front of the camera (x <= 0) has no image; its row is NaN.
        """
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        front = p[:, 0] > 0
        if self.distorted:
            import cv2

            uv = np.full((len(p), 2), np.nan)
            if np.any(front):
                zero = np.zeros(3)
                cv = camera_to_cv(p[front]).reshape(-1, 1, 3)
                uv[front] = cv2.projectPoints(cv, zero, zero, self.K, self.dist)[0].reshape(-1, 2)
            return uv
        with np.errstate(divide="ignore", invalid="ignore"):
            # OpenCV's normalised coordinates: x right = -y_c / x_c, y down = -z_c / x_c.
            a, b = -p[:, 1] / p[:, 0], -p[:, 2] / p[:, 0]
        K = self.K
        uv = np.empty((len(p), 2))
        uv[:, 0], uv[:, 1] = K[0, 0] * a + K[0, 1] * b + K[0, 2], K[1, 1] * b + K[1, 2]
        if not front.all():
            uv[~front] = np.nan
        return uv

    def contains(self, uv: np.ndarray) -> np.ndarray:
        """Which pixels (N, 2) lie inside the image (N,) bool."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        with np.errstate(invalid="ignore"):
            return (
                (uv[:, 0] >= -0.5)
                & (uv[:, 0] <= self.width - 0.5)
                & (uv[:, 1] >= -0.5)
                & (uv[:, 1] <= self.height - 0.5)
            )


def _distort(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """OpenCV's radial-tangential lens model (up to 8 coefficients) on normalised coordinates."""
    k = np.zeros(8)
    k[: dist.size] = dist
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = (1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]))) / (
        1 + r2 * (k[5] + r2 * (k[6] + r2 * k[7]))
    )
    dx = 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x)
    dy = k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y
    return np.column_stack([x * radial + dx, y * radial + dy])


def load_intrinsics(path: str | Path) -> CameraModel:
    """Intrinsics from an OpenCV YAML/XML file or a JSON file with ``camera_matrix`` (3x3 or 9
    numbers), ``distortion_coefficients`` and ``image_width``/``image_height``."""
    path = Path(path)
    if not path.is_file():
        what = "a folder, not a file" if path.is_dir() else "file not found"
        raise CalibrationError(f"{path}: intrinsics {what}")
    read = _read_json if path.suffix.lower() == ".json" else _read_opencv
    K, dist, width, height = read(path)
    if K is None:
        raise CalibrationError(f"{path}: camera_matrix missing")
    try:
        K = np.asarray(K, dtype=float).reshape(-1)
        dist = np.zeros(0) if dist is None else np.asarray(dist, dtype=float).reshape(-1)
        width, height = _number(width or 0), _number(height or 0)
    except (TypeError, ValueError):
        raise CalibrationError(
            f"{path}: camera_matrix, distortion_coefficients, image_width "
            "and image_height must be numbers"
        ) from None
    if K.size != 9 or not np.isfinite(K).all() or K[0] <= 0 or K[4] <= 0:
        raise CalibrationError(f"{path}: camera_matrix must be 3x3 with positive f_x, f_y")
    if dist.size not in (0, 4, 5, 8, 12, 14) or not np.isfinite(dist).all():
        raise CalibrationError(
            f"{path}: distortion_coefficients needs 4, 5, 8, 12 or 14 numbers, got {dist.size}"
        )
    if not (1 <= width <= _MAX_SIDE and 1 <= height <= _MAX_SIDE):
        raise CalibrationError(f"{path}: image_width and image_height (1-{_MAX_SIDE}) are needed")
    return CameraModel(K=K.reshape(3, 3), dist=dist, width=int(width), height=int(height))


_MAX_SIDE = 65535


def _number(value: object) -> float:
    """``float(value)`` of what ``float`` reads; anything else (a list, a table) is a TypeError,
    as ``float`` itself would raise."""
    if isinstance(value, str | int | float):
        return float(value)
    raise TypeError(f"not a number: {value!r}")


def _read_json(path: Path) -> tuple[object, object, object, object]:
    """camera_matrix, distortion_coefficients, image_width, image_height of a JSON file."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:
        raise CalibrationError(f"{path}: not valid JSON: {err}") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: expected a JSON object with camera_matrix")
    K, dist = data.get("camera_matrix"), data.get("distortion_coefficients", [])
    return K, dist, data.get("image_width"), data.get("image_height")


def _read_opencv(path: Path) -> tuple[object, object, object, object]:
    """The same four of an OpenCV YAML/XML file."""
    import cv2

    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        if not fs.isOpened():
            raise CalibrationError(f"{path}: cannot read as OpenCV YAML/XML")
        try:
            K = fs.getNode("camera_matrix").mat()
            dist = fs.getNode("distortion_coefficients").mat()
            width = fs.getNode("image_width").real() or None
            height = fs.getNode("image_height").real() or None
        finally:
            fs.release()
    # OpenCV's parser reports a damaged file as cv2.error, or (random bytes) as a SystemError
    # from its Python binding.
    except (cv2.error, SystemError) as err:
        detail = f" ({err.err})" if isinstance(err, cv2.error) else ""
        raise CalibrationError(f"{path}: not an OpenCV YAML/XML intrinsics file{detail}") from None
    return K, dist, width, height


def save_intrinsics(path: str | Path, camera: CameraModel, **extra: float | str) -> None:
    """Write intrinsics as OpenCV YAML (``.yml``/``.yaml``/``.xml``) or JSON (``.json``);
    ``extra`` scalars (e.g. ``rms``) are written alongside."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        data = {
            "image_width": camera.width,
            "image_height": camera.height,
            "camera_matrix": camera.K.tolist(),
            "distortion_coefficients": camera.dist.tolist(),
            **extra,
        }
        path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
        return
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", camera.width)
    fs.write("image_height", camera.height)
    fs.write("camera_matrix", camera.K)
    fs.write("distortion_coefficients", camera.dist.reshape(1, -1))
    for key, value in extra.items():
        fs.write(key, value)
    fs.release()
