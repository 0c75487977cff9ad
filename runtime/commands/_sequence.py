"""Frame sequences for the offline perception commands (``track``, ``foreground``).

A source is a video file, a folder of images, a MOTChallenge sequence folder (``img1/`` and
``seqinfo.ini``; a folder with ``seqinfo.ini`` and one video, as in ``mot15-tud``, works too), or
a daemon's recording (``percept run --record``, ``.mcap``). Frames come with a name (the image's
file stem, ``000001``... for video frames, the frame's ``seq`` in a recording) and a time in
seconds from the frame rate (``seqinfo.ini``, the video's, or 25), or as recorded.

Some sources also hold the robot's joint angles at each frame (:meth:`Sequence.joint_angles`):
a folder written by ``percept sim`` (``joints.csv``) and a recording (each frame's inputs).
"""

from __future__ import annotations

import configparser
import csv
import logging
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from percept.config.loader import ConfigError

if TYPE_CHECKING:
    import numpy as np

    from percept.perception.segmentation.grid_frame import PerceptionFrame
    from percept.runtime.daemon.pipeline import FrameInputs
    from percept.runtime.record.reader import RecordedFrame

log = logging.getLogger("percept.sequence")

IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".ppm", ".pgm"}
VIDEO_SUFFIXES = {".mp4", ".avi", ".mkv", ".mov", ".webm", ".mpg", ".mpeg", ".m4v"}
DEFAULT_FPS = 25.0
SIM_SECTION = "percept"
"""The section of ``seqinfo.ini`` where ``percept sim`` says what it simulated: ``scene``,
``robot`` and ``profile`` (shipped names, or absolute paths)."""


@dataclass(frozen=True)
class Sequence:
    """Where the frames of one source are and how fast they were taken."""

    path: Path
    images: tuple[Path, ...] | None
    """The image files in order, or None for a video or a recording."""
    video: Path | None
    fps: float
    recording: Path | None = None
    """An MCAP recording of the daemon (then ``images`` and ``video`` are None)."""
    calibration_frames: int | None = None
    """How many first frames show the scene for the background calibration, when the folder
    says (``calibrationFrames`` in ``seqinfo.ini``, written by ``percept sim``)."""

    def frames(
        self, limit: int | None = None, step: int = 1
    ) -> Iterator[tuple[str, float, PerceptionFrame | None]]:
        """(name, time, image) per frame; the image is None when it cannot be decoded.

        ``step`` 1: full-size BGR images. Else perception's grid frames of that step, as the
        daemon's camera gives them: image files as the image-folder camera reads them (a JPEG
        decoded at the grid's scale), video and recorded frames averaged over each block.
        """
        if self.images is not None:
            for i, path in enumerate(self.images[:limit]):
                yield path.stem, i / self.fps, _image_file(path, step)
            return
        for name, t, image in self._full_frames(limit):
            yield name, t, image if step == 1 else _on_grid(image, step)

    def _full_frames(self, limit: int | None) -> Iterator[tuple[str, float, np.ndarray]]:
        """(name, time, BGR image) per frame of a recording or a video."""
        import cv2

        if self.recording is not None:
            for i, (inputs, frame) in enumerate(_recorded_frames(self.recording)):
                if limit is not None and i >= limit:
                    break
                yield f"{inputs.seq:06d}", inputs.t, frame.image
            return
        capture = cv2.VideoCapture(str(self.video))
        try:
            i = 0
            while limit is None or i < limit:
                ok, image = capture.read()
                if not ok:
                    break
                yield f"{i + 1:06d}", i / self.fps, image
                i += 1
        finally:
            capture.release()

    def search_image(self, index: int, step: int) -> np.ndarray | None:
        """Frame ``index``'s (from 0) full-size grey image from an image folder, as the daemon's
        marker search reads it from the image-folder camera with perception's grid of ``step``
        (a JPEG's luma where the camera decodes the grid at a reduced scale, else the BGR
        image's grey); None for other sources or an image that does not decode."""
        from percept.drivers.camera.base import Capture, gray_image
        from percept.drivers.camera.image_file import ImageFileError, read_grid_image

        if self.images is None:
            return None
        try:
            image = read_grid_image(self.images[index], step)
        except ImageFileError as err:
            log.warning("%s", err)
            return None
        if isinstance(image, Capture):
            return gray_image(image.full, image.luma)
        return gray_image(lambda: image, None)

    def joint_angles(self) -> list[dict[str, float] | None]:
        """The joint angles at each frame, in order (None for a recorded frame without a joint
        reading); a :class:`ConfigError` when the source holds none."""
        if self.recording is not None:
            return [
                dict(inputs.joints) if inputs.joints else None
                for inputs, _ in _recorded_frames(self.recording)
            ]
        table = self.path / "joints.csv"
        if not table.is_file():
            raise ConfigError(
                self.path,
                "",
                "no recorded joint angles: expected a percept sim folder (joints.csv) or a "
                "recording (.mcap)",
            )
        with table.open(newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        try:
            by_frame = {
                int(r["frame"]): {k: float(v) for k, v in r.items() if k not in ("frame", "t")}
                for r in rows
            }
        except (KeyError, TypeError, ValueError) as err:
            raise ConfigError(table, "", f"not a percept sim joints table: {err}") from None
        count = len(self.images or ())
        missing = [k for k in range(1, count + 1) if k not in by_frame]
        if missing:
            raise ConfigError(table, "", f"no joint angles for frame {missing[0]}")
        return [by_frame[k] for k in range(1, count + 1)]

    def recorded_profile(self) -> str | None:
        """The robot profile a ``percept sim`` folder names (``seqinfo.ini``'s ``[percept]
        profile``), for its ``joints.csv``: None for any other source, or an older folder."""
        ini = self.path / "seqinfo.ini"
        if self.images is None or not (self.path / "joints.csv").is_file() or not ini.is_file():
            return None
        parser = configparser.ConfigParser()
        parser.read(ini)
        return parser.get(SIM_SECTION, "profile", fallback=None)

    def size(self) -> tuple[int, int]:
        """(width, height) of the first frame that decodes."""
        import numpy as np

        for _, _, image in self.frames():
            if isinstance(image, np.ndarray):
                return image.shape[1], image.shape[0]
        raise ConfigError(self.path, "", "no frame could be decoded")


def _image_file(path: Path, step: int) -> PerceptionFrame | None:
    """An image file as the image-folder camera reads it for perception's grid of ``step``
    (None when it cannot be decoded: reported, the frame counts as skipped)."""
    import numpy as np

    from percept.drivers.camera.image_file import ImageFileError, read_grid_image
    from percept.perception.segmentation.grid_frame import GridFrame

    try:
        image = read_grid_image(path, step)
    except ImageFileError as err:
        log.warning("%s", err)
        return None
    if isinstance(image, np.ndarray):
        return image
    return GridFrame.of(image.grid, image.step, image.colour)


def _on_grid(image: np.ndarray, step: int) -> PerceptionFrame:
    """A full-size BGR frame as a grid frame of ``step``: each grid pixel its block's average."""
    from percept.drivers.camera.decode import area_grid
    from percept.perception.segmentation.grid_frame import GridFrame

    return GridFrame.of(area_grid(image, step), step)


def _natural(path: Path) -> list[object]:
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", path.name)]


def _images(folder: Path) -> tuple[Path, ...]:
    return tuple(
        sorted((p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES), key=_natural)
    )


def _seqinfo(folder: Path) -> configparser.SectionProxy | None:
    """The ``[Sequence]`` section of the folder's ``seqinfo.ini``, if it has one."""
    ini = folder / "seqinfo.ini"
    if not ini.is_file():
        return None
    parser = configparser.ConfigParser()
    parser.read(ini)
    return parser["Sequence"] if parser.has_section("Sequence") else None


def _seqinfo_fps(folder: Path) -> float | None:
    section = _seqinfo(folder)
    return None if section is None else section.getfloat("frameRate", fallback=None)


def _seqinfo_calibration(folder: Path) -> int | None:
    section = _seqinfo(folder)
    if section is None or "calibrationFrames" not in section:
        return None
    try:
        frames = section.getint("calibrationFrames")
    except ValueError:
        frames = None
    if frames is None or frames < 1:
        raise ConfigError(
            folder / "seqinfo.ini",
            "Sequence.calibrationFrames",
            f"expected a whole number of frames above 0, got {section.get('calibrationFrames')!r}",
        )
    return frames


def open_sequence(source: str | Path) -> Sequence:
    """The sequence at ``source``; a :class:`ConfigError` when it is none of the known kinds."""
    import cv2

    path = Path(source)
    if path.is_file() and path.suffix.lower() == ".mcap":
        return Sequence(path, None, None, DEFAULT_FPS, recording=path)
    if path.is_file():
        if path.suffix.lower() not in VIDEO_SUFFIXES:
            raise ConfigError(path, "", "not a video file (or give a folder of images)")
        capture = cv2.VideoCapture(str(path))
        fps = capture.get(cv2.CAP_PROP_FPS) if capture.isOpened() else 0.0
        capture.release()
        fps = _seqinfo_fps(path.parent) or fps or DEFAULT_FPS
        return Sequence(path, None, path, fps)
    if not path.is_dir():
        raise ConfigError(path, "", "no such file or folder")
    fps = _seqinfo_fps(path) or DEFAULT_FPS
    if (path / "img1").is_dir():
        return Sequence(path, _images(path / "img1"), None, fps, None, _seqinfo_calibration(path))
    images = _images(path)
    if images:
        return Sequence(path, images, None, fps)
    videos = sorted(p for p in path.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
    if len(videos) == 1:
        return open_sequence(videos[0])
    raise ConfigError(path, "", "no images, img1/ folder or single video in this folder")


def _recorded_frames(path: Path) -> Iterator[tuple[FrameInputs, RecordedFrame]]:
    """The frames of a recording with their inputs, in order; a :class:`ConfigError` for a file
    that is not a recording."""
    from percept.runtime.daemon.pipeline import FrameInputs
    from percept.runtime.record.reader import RecordingError, read_recording

    try:
        for kind, item in read_recording(path):
            if kind == "frame":
                yield FrameInputs.from_record(item.inputs), item
    except RecordingError as err:
        raise ConfigError(path, "", str(err)) from None
