"""Frames through cv2.VideoCapture: a device, a V4L2 path, a GStreamer pipeline or a video file."""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np

from percept.drivers.camera.base import EndOfStream, FrameSource, SourceUnavailable
from percept.drivers.camera.settings import CameraSettings

log = logging.getLogger("percept.camera")


class OpenCVCamera(FrameSource):
    """A camera or video file read with ``cv2.VideoCapture``.

    ``settings.source`` is a device index (``"0"``), a ``/dev/...`` path (read through V4L2; prefer
    the stable ``/dev/v4l/by-id/...`` links), a GStreamer pipeline (contains ``!``; it must end in
    an ``appsink``) or a video file. Devices are asked for the configured width, height and frame
    rate (a pipeline states its own caps); both pace themselves. A file is paced by
    ``settings.pace``, and its end finishes the source unless ``settings.loop``.
    """

    def __init__(self, settings: CameraSettings) -> None:
        super().__init__(settings)
        source = settings.source
        self._device: int | str | None = None
        self._backend = cv2.CAP_ANY
        if "!" in source:
            self._backend = cv2.CAP_GSTREAMER
        elif source.isdigit():
            self._device = int(source)
        elif source.startswith("/dev/"):
            self._device, self._backend = source, cv2.CAP_V4L2
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

    def _read(self) -> np.ndarray | None:
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
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image

    def _close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None
