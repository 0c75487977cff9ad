"""Frames from a folder of image files, in name order."""

from __future__ import annotations

import bisect
import logging
from pathlib import Path

import numpy as np

from percept.drivers.camera.base import Capture, EndOfStream, FrameSource, SourceUnavailable
from percept.drivers.camera.image_file import ImageFileError, read_grid_image
from percept.drivers.camera.settings import CameraSettings

log = logging.getLogger("percept.camera.folder")

SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".bmp"})


class ImageFolderCamera(FrameSource):
    """The PNG, JPEG and BMP files of ``settings.source`` in sorted name order.

    Paced by ``settings.pace``; finishes after the last file unless ``settings.loop``. The folder
    is listed again on every (re)open, and reading resumes after the last file read, so files
    added while it runs are picked up. With ``settings.epoch``, file ``i`` is the one due at
    ``epoch + i / fps``: the files stand for a recording's frames, taken at those times. With a
    ``grid_step`` above 1 each file is read as
    :func:`~percept.drivers.camera.image_file.read_grid_image` reads it: a JPEG decoded at the
    grid's scale, its full size only when a frame's ``image`` is asked for.
    """

    def __init__(self, settings: CameraSettings, grid_step: int = 1) -> None:
        super().__init__(settings, grid_step)
        self._folder = Path(settings.source)
        self._files: list[str] = []
        self._next = 0
        self._last = ""  # name of the last file read

    def _open(self) -> None:
        if not self._folder.is_dir():
            raise SourceUnavailable(f"no such folder: {self._folder}")
        files = sorted(p.name for p in self._folder.iterdir() if p.suffix.lower() in SUFFIXES)
        if not files:
            raise OSError(f"no image files in {self._folder}")
        self._files = files
        self._next = bisect.bisect_right(files, self._last)

    def _read(self) -> np.ndarray | Capture | None:
        if self._in_step:
            due = self._read_number
            self._next = due % len(self._files) if self.settings.loop else due
        if self._next >= len(self._files):
            if not self.settings.loop:
                raise EndOfStream(str(self._folder))
            self._next = 0
        name = self._files[self._next]
        self._next += 1
        try:
            image = read_grid_image(self._folder / name, self.grid_step)
        except ImageFileError as err:
            # Reported and passed over: a reconnect resumes after it, not at it again.
            log.warning("skipped: %s", err)
            self._last = name
            return None
        self._last = name
        return image

    def _close(self) -> None:
        self._files = []
