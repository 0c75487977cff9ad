"""Calibrating the moving-head background: empty-scene frames at any head poses into the mosaic,
and the mosaic back into one view as a still model; the calibration's file.

A calibration whose frames were all taken at one pose (a still head) keeps the per-pixel model
of §4.1 from them, exact for frames taken at that pose, beside the mosaic for any other pose;
one taken while the head moved has the mosaic only (and, for what asks for one view, the mosaic
as seen from its last pose).

Each calibration frame is resampled into the cells of the map that the frames saw (with
bilinear interpolation of the full image, where the frames are later worked on a grid), and
each cell's statistics are taken over the frames that saw it (at least
:data:`~percept.perception.view.mosaic.MIN_VIEWS` of them, else it stays unknown). The map
reaches half a view beyond the calibrated directions on every side, so that what the head sees
there can be learned later.
"""

from __future__ import annotations

import math
import zipfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose
from percept.perception.params import PerceptionParams
from percept.perception.segmentation.background import BackgroundModel, CalibrationError, Progress
from percept.perception.segmentation.grid_frame import (
    GridFrame,
    PerceptionFrame,
    as_ycrcb,
    grid_ycrcb,
)
from percept.perception.view.follow import grid_camera_matrix, same_view
from percept.perception.view.map.directions import Lookup, direction_map
from percept.perception.view.mosaic import ViewMosaic
from percept.perception.view.register import lagged, motions, pose_lag

UNKNOWN_SIGMA = 255.0
"""Deviation given to an unknown direction in a still model: its bounds span 0-255."""


@dataclass(frozen=True)
class ViewCalibration:
    """What a calibration with camera poses gives."""

    model: BackgroundModel
    """The per-pixel model: of a still head's frames, else the mosaic seen from ``last``."""
    mosaic: ViewMosaic
    still_pose: CameraPose | None
    """Where the head was, when it held still for the whole calibration."""
    last: CameraPose | None
    """The pose of the last calibration frame (None when loaded from a file)."""
    lag: float = 0.0
    """Frames the poses lag behind the images (:func:`~percept.perception.view.register.
    pose_lag`; 0 for a still head's calibration)."""


def calibrate_view(
    frames_in: Iterable[PerceptionFrame],
    poses: Iterable[CameraPose],
    camera: CameraModel,
    step: int,
    params: PerceptionParams,
    progress: Progress | None = None,
) -> ViewCalibration:
    """The background of the first ``background.calibration_frames`` frames taken at
    ``poses``, worked on the grid of every ``step``-th pixel. The frames are full-size BGR
    images, or grid frames: the per-pixel model is then of the grid."""
    total = params.background.calibration_frames
    frames: list[PerceptionFrame] = []
    taken: list[CameraPose] = []
    for frame, pose in zip(frames_in, poses, strict=False):  # poses may run on
        frames.append(frame)
        taken.append(pose)
        if progress is not None:
            progress(len(frames), total)
        if len(frames) >= total:
            break
    if not frames:
        raise CalibrationError("no calibration frames")
    first = frames[0]
    height, width = (
        (camera.height, camera.width) if isinstance(first, GridFrame) else first.shape[:2]
    )
    K, grid = grid_camera_matrix(camera, step), (width / step, height / step)
    if all(same_view(K, grid, taken[0], p) for p in taken):
        mosaic = calibrate_mosaic(frames, taken, camera, step, params)
        model = BackgroundModel.calibrate(frames, params.background)
        return ViewCalibration(model, mosaic, taken[0], taken[-1])

    def build(poses: list[CameraPose]) -> ViewMosaic:
        return calibrate_mosaic(frames, poses, camera, step, params)

    lag = 0.0
    if params.view.refine:
        brightness = [grid_ycrcb(f, step)[..., 0] for f in frames]
        max_turn = math.radians(params.view.max_shift)
        lag, mosaic = pose_lag(build, brightness, taken, camera, step, K, max_turn)
        taken = lagged(taken, motions(taken), lag)
    else:
        mosaic = build(taken)
    if isinstance(first, GridFrame):  # the per-pixel model is of the frames as they come
        model = still_model(mosaic, camera, taken[-1], step, first.ycc.shape[:2])
    else:
        model = still_model(mosaic, camera, taken[-1], 1, (height, width))
    return ViewCalibration(model, mosaic, None, taken[-1], lag)


def save(path: str | Path, calibration: ViewCalibration) -> None:
    """Write the per-pixel model (``mean``, ``sigma``, as :meth:`BackgroundModel.save`), the
    mosaic and the still pose to one ``.npz`` file."""
    model = calibration.model
    arrays = {"mean": model.mean, "sigma": model.sigma} | calibration.mosaic.arrays()
    arrays["pose_lag"] = np.array(calibration.lag)
    if calibration.still_pose is not None:
        arrays |= {"still_R": calibration.still_pose.R, "still_t": calibration.still_pose.t}
    np.savez_compressed(path, allow_pickle=False, **arrays)


def load(
    path: str | Path, model: BackgroundModel, params: PerceptionParams
) -> ViewCalibration | None:
    """The calibration in ``path`` whose per-pixel ``model`` was read already, or None when
    the file holds no mosaic (a calibration without poses)."""
    mosaic = ViewMosaic.load(path, params.background, params.view, params.motion.k)
    if mosaic is None:
        return None
    still_pose = None
    lag = 0.0
    try:
        with np.load(path) as data:
            if "still_R" in data and "still_t" in data:
                still_pose = CameraPose(R=data["still_R"], t=data["still_t"])
            if "pose_lag" in data:  # (files written before the lag was found have none)
                lag = float(data["pose_lag"])
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        raise CalibrationError(f"{path}: not a moving-head background ({err})") from None
    return ViewCalibration(model, mosaic, still_pose, None, lag)


def calibrate_mosaic(
    frames: list[PerceptionFrame],
    poses: list[CameraPose],
    camera: CameraModel,
    step: int,
    params: PerceptionParams,
) -> ViewMosaic:
    """The mosaic of empty-scene ``frames`` (full-size BGR images or grid frames) taken at
    ``poses`` by ``camera``, at the angular size of the grid of every ``step``-th pixel."""
    margin = max(camera.opening_angles()) / 2
    directions, box = direction_map(poses, camera, step, margin)
    left, top, width, height = box
    samples = np.empty((len(frames), height, width, 3), np.uint8)
    seen = np.empty((len(frames), height, width), bool)
    seen[:] = False
    for i, (frame, pose) in enumerate(zip(frames, poses, strict=True)):
        x, y, w, h = _within(directions.footprint(pose, camera), box)
        if w == 0 or h == 0:
            continue
        uv = directions.cell_pixels(pose, camera, (x, y, w, h))
        inside = camera.contains(uv.reshape(-1, 2)).reshape(h, w)
        seen[i, y - top : y - top + h, x - left : x - left + w] = inside
        if isinstance(frame, GridFrame):  # grid pixel j is image pixel j step (as on_grid)
            uv = uv / np.float32(frame.step)
        samples[i, y - top : y - top + h, x - left : x - left + w] = cv2.remap(
            as_ycrcb(frame), uv[..., 0], uv[..., 1], cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )  # fmt: skip
    return ViewMosaic.calibrate(
        directions, samples, seen, box, params.background, params.view, params.motion.k
    )


def still_model(
    mosaic: ViewMosaic, camera: CameraModel, pose: CameraPose, step: int, shape: tuple[int, int]
) -> BackgroundModel:
    """The mosaic as the per-pixel model of the view from ``pose``: of its grid of every
    ``step``-th pixel, (rows, columns) ``shape`` (unknown directions never foreground)."""
    cells = Lookup(camera, step, shape)(mosaic.directions, pose)
    mx, my = cells[..., 0], cells[..., 1]
    mean = cv2.remap(mosaic.mean, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    sigma = cv2.remap(mosaic.sigma, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    known = cv2.remap(
        mosaic.known.astype(np.uint8), mx, my, cv2.INTER_NEAREST, borderValue=0
    ).astype(bool)
    sigma[~known] = UNKNOWN_SIGMA
    return BackgroundModel(mean, sigma, mosaic.background)


Box = tuple[int, int, int, int]


def _within(a: Box, b: Box) -> Box:
    """The part of box ``a`` inside box ``b`` (left, top, width, height; may be empty)."""
    x0, y0 = max(a[0], b[0]), max(a[1], b[1])
    x1, y1 = min(a[0] + a[2], b[0] + b[2]), min(a[1] + a[3], b[1] + b[3])
    return x0, y0, max(x1 - x0, 0), max(y1 - y0, 0)
