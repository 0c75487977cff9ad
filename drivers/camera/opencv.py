"""Frames through cv2.VideoCapture: a device, a V4L2 path, a GStreamer pipeline or a video file."""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np

from percept.drivers.camera.base import Capture, EndOfStream, FrameSource, SourceUnavailable
from percept.drivers.camera.decode import yuyv_luma, yuyv_to_bgr, yuyv_to_ycrcb
from percept.drivers.camera.settings import CameraSettings, is_device

log = logging.getLogger("percept.camera")


class OpenCVCamera(FrameSource):
    """A camera or video file read with ``cv2.VideoCapture``.

    ``settings.source`` is a device index (``"0"``), a ``/dev/...`` path (read through V4L2; prefer
    the stable ``/dev/v4l/by-id/...`` links), a GStreamer pipeline (contains ``!``; it must end in
    an ``appsink``) or a video file. Devices are asked for the configured width, height and frame
    rate (a pipeline states its own caps); both pace themselves. A file is paced by
    ``settings.pace``, and its end finishes the source unless ``settings.loop``.

    With ``settings.pixel_format`` ``"yuyv"`` a device is read raw (``CAP_PROP_FOURCC`` YUYV,
    ``CAP_PROP_CONVERT_RGB`` 0): each frame's grid is YCrCb straight from the YUYV bytes, its
    BGR image made only when asked for, its grey image (the marker search's) from the luma.
    """

    def __init__(self, settings: CameraSettings, grid_step: int = 1) -> None:
        super().__init__(settings, grid_step)
        source = settings.source
        self._device: int | str | None = None
        self._backend = cv2.CAP_ANY
        if "!" in source:
            self._backend = cv2.CAP_GSTREAMER
        elif source.isdigit():
            self._device = int(source)
        elif is_device(source):
            self._device, self._backend = source, cv2.CAP_V4L2
        self._raw = settings.pixel_format == "yuyv"
        self.live = self._device is not None or self._backend == cv2.CAP_GSTREAMER
        self._cap: cv2.VideoCapture | None = None

    def _open(self) -> None:
        source = self.settings.source
        if self._backend == cv2.CAP_GSTREAMER and not cv2.videoio_registry.hasBackend(
            cv2.CAP_GSTREAMER
        ):
            raise SourceUnavailable("this OpenCV was built without GStreamer")
        if isinstance(self._device, str) and not Path(source).exists():
            raise OSError(f"{source} does not exist (unplugged?)")
        if not self.live and not Path(source).is_file():
            raise SourceUnavailable(f"no such video file: {source}")
        cap = cv2.VideoCapture(source if self._device is None else self._device, self._backend)
        if not cap.isOpened():
            cap.release()
            raise OSError(f"OpenCV cannot open {source}")
        if self._device is not None:
            cap.set(cv2.CAP_PROP_FRAME_WIDTH, self.settings.width)
            cap.set(cv2.CAP_PROP_FRAME_HEIGHT, self.settings.height)
            cap.set(cv2.CAP_PROP_FPS, self.settings.fps)
            cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # a driver queue would hand out old frames
            if self._raw and not _raw_yuyv(cap):
                cap.release()
                raise SourceUnavailable(f"{source} gives no raw YUYV (pixel_format yuyv)")
        size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if size != (self.settings.width, self.settings.height):
            log.warning(
                "%s: delivers %dx%d, configured %dx%d (intrinsics assume the configured size)",
                self,
                *size,
                self.settings.width,
                self.settings.height,
            )
        self._cap = cap

    def _read(self) -> np.ndarray | Capture | None:
        assert self._cap is not None
        ok, image = self._cap.read()
        if not ok and not self.live:
            # a file has no unplug: a failed read is its end
            if not self.settings.loop:
                raise EndOfStream(self.settings.source)
            self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
            ok, image = self._cap.read()
        if not ok:
            return None
        if self._raw:
            return raw_capture(image, self.settings.width, self.settings.height, self.grid_step)
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image

    def _close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


def _raw_yuyv(cap: cv2.VideoCapture) -> bool:
    """Ask the device for raw YUYV, not converted to BGR; whether it agreed."""
    cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*"YUYV"))
    cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
    fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little")
    return fourcc == b"YUYV" and cap.get(cv2.CAP_PROP_CONVERT_RGB) == 0


def raw_capture(raw: np.ndarray, width: int, height: int, step: int) -> Capture | None:
    """A raw YUYV frame as OpenCV hands it over (``(H, W, 2)``, or one row of ``2 W H`` bytes)
    as a capture on the grid of ``step``; None when its size is not ``width`` x ``height``."""
    if raw.size != 2 * width * height:
        return None
    yuyv = raw.reshape(height, width, 2)
    grid = yuyv_to_ycrcb(yuyv, step)
    return Capture(grid, step, "ycrcb", lambda: yuyv_to_bgr(yuyv), lambda: yuyv_luma(yuyv))
