"""Camera sources: OpenCV devices, pipelines and files, image folders; see :mod:`.base`."""

from __future__ import annotations

from pathlib import Path

from percept.drivers.camera.base import (
    CameraError,
    CameraState,
    Capture,
    EndOfStream,
    Frame,
    FrameSource,
    SourceUnavailable,
)
from percept.drivers.camera.folder import ImageFolderCamera
from percept.drivers.camera.opencv import OpenCVCamera
from percept.drivers.camera.settings import CameraSettings

__all__ = [
    "CameraError",
    "CameraSettings",
    "CameraState",
    "Capture",
    "EndOfStream",
    "Frame",
    "FrameSource",
    "ImageFolderCamera",
    "OpenCVCamera",
    "SourceUnavailable",
    "open_camera",
]


def open_camera(settings: CameraSettings, grid_step: int = 1) -> FrameSource:
    """The source ``settings.source`` describes, not yet started; ``grid_step``: perception's
    grid step, at whose size a folder of JPEG files and a raw camera give their frames.

    A folder gives an :class:`ImageFolderCamera`, anything else an :class:`OpenCVCamera`.
    ``"sim"`` raises :class:`CameraError`: the simulated camera renders the simulated world, so
    it is built together with that world in ``percept.drivers.sim``.
    """
    if settings.source == "sim":
        raise CameraError(
            'camera source "sim" is rendered by the simulated world: build the simulated camera '
            "from drivers.sim, not with open_camera()"
        )
    if "!" not in settings.source and Path(settings.source).is_dir():
        return ImageFolderCamera(settings, grid_step)
    return OpenCVCamera(settings, grid_step)
