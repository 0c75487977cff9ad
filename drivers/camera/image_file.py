"""Image files read with their declared size checked first.

A PNG of a few kilobytes can declare 60000x60000 pixels, and a 1 MB one can inflate to gigabytes:
OpenCV allocates what the header says before it decodes. OpenCV's own guard
(``OPENCV_IO_MAX_IMAGE_PIXELS``, 2^30 pixels) is read once when the library loads and fails with
an exception that names no file, so every tool that reads image files goes through
:func:`read_image`: it reads the width and height from the file's header (PNG ``IHDR``, JPEG
``SOFn``, BMP info header, TIFF directory, PNM header) without decoding and refuses more than
:func:`max_pixels` pixels (environment variable ``PERCEPT_MAX_IMAGE_PIXELS``, default 8192 x
8192). Every problem is an :class:`ImageFileError` naming the file, so that a tool can report it
and go on with the next.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import BinaryIO

import cv2
import numpy as np

from percept.drivers.camera.base import Capture
from percept.drivers.camera.decode import REDUCED_FLAGS, area_grid, decode_jpeg, decode_jpeg_luma

MAX_PIXELS_VARIABLE = "PERCEPT_MAX_IMAGE_PIXELS"
DEFAULT_MAX_PIXELS = 8192 * 8192

_PNG = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers: every SOFn but DHT (C4), JPG (C8) and DAC (CC).
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
_NO_LENGTH = frozenset({0x01, *range(0xD0, 0xD8)})  # TEM and RSTn stand alone


class ImageFileError(ValueError):
    """An image file that cannot be read: missing, not an image, too large or damaged."""


def max_pixels() -> int:
    """The largest ``width * height`` an image file may declare."""
    raw = os.environ.get(MAX_PIXELS_VARIABLE)
    if raw is None:
        return DEFAULT_MAX_PIXELS
    try:
        value = int(raw)
    except ValueError:
        value = 0
    if value < 1:
        raise ImageFileError(f"{MAX_PIXELS_VARIABLE}={raw!r}: expected a positive integer")
    return value


def declared_size(path: str | Path) -> tuple[int, int]:
    """(width, height) that a PNG, JPEG, BMP, TIFF or PNM file's header declares, read without
    decoding."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(26)
            if head.startswith(_PNG) and head[12:16] == b"IHDR":
                return struct.unpack(">II", head[16:24])
            if head.startswith(b"\xff\xd8"):
                fh.seek(2)
                return _jpeg_size(fh, path)
            if head.startswith(b"BM") and len(head) >= 26:
                if struct.unpack("<I", head[14:18])[0] == 12:  # OS/2 core header: 16-bit sizes
                    return struct.unpack("<HH", head[18:22])
                width, height = struct.unpack("<ii", head[18:26])
                return abs(width), abs(height)  # a negative height: rows stored top-down
            if head[:4] in (b"II*\0", b"MM\0*") and len(head) >= 8:
                return _tiff_size(fh, "<" if head[:1] == b"I" else ">", head, path)
            if head[:1] == b"P" and head[1:2] in b"123456" and len(head) > 2:
                fh.seek(2)
                return _pnm_size(fh.read(4096), path)
    except OSError as err:
        raise ImageFileError(f"{path}: cannot read: {err.strerror}") from None
    raise ImageFileError(f"{path}: not a PNG, JPEG, BMP, TIFF or PNM image")


def _jpeg_size(fh: BinaryIO, path: str | Path) -> tuple[int, int]:
    """Walk the JPEG's segments to its frame header (after any EXIF or other metadata)."""
    while True:
        byte = fh.read(1)
        if not byte:
            break
        if byte != b"\xff":
            continue
        marker = fh.read(1)
        while marker == b"\xff":  # fill bytes
            marker = fh.read(1)
        if not marker:
            break
        code = marker[0]
        if code in _NO_LENGTH or code == 0x00:
            continue
        if code in (0xD9, 0xDA):  # end of image or start of scan before any frame header
            break
        length = fh.read(2)
        if len(length) < 2:
            break
        size = struct.unpack(">H", length)[0]
        if code in _SOF:
            frame = fh.read(5)
            if len(frame) < 5:
                break
            height, width = struct.unpack(">HH", frame[1:5])
            return width, height
        fh.seek(size - 2, os.SEEK_CUR)
    raise ImageFileError(f"{path}: damaged JPEG: no frame header")


def _tiff_size(fh: BinaryIO, order: str, head: bytes, path: str | Path) -> tuple[int, int]:
    """ImageWidth (tag 256) and ImageLength (257) of a TIFF's first directory."""
    try:
        fh.seek(struct.unpack(order + "I", head[4:8])[0])
        (entries,) = struct.unpack(order + "H", fh.read(2))
        size: dict[int, int] = {}
        for _ in range(entries):
            tag, kind, _count, value = struct.unpack(order + "HHI4s", fh.read(12))
            if tag in (256, 257):
                short = kind == 3  # SHORT, else LONG
                size[tag] = struct.unpack(
                    order + ("H" if short else "I"), value[: 2 if short else 4]
                )[0]
            if len(size) == 2:
                return size[256], size[257]
    except struct.error:
        pass
    raise ImageFileError(f"{path}: damaged TIFF: no image width and length")


def _pnm_size(text: bytes, path: str | Path) -> tuple[int, int]:
    """Width and height of a PBM/PGM/PPM header (after the two-byte magic, comments allowed)."""
    words = b" ".join(line.split(b"#", 1)[0] for line in text.splitlines()).split()
    if len(words) >= 2 and words[0].isdigit() and words[1].isdigit():
        return int(words[0]), int(words[1])
    raise ImageFileError(f"{path}: damaged PNM header")


def _check_declared_size(path: str | Path) -> None:
    """Raise :class:`ImageFileError` unless the file declares a size within :func:`max_pixels`."""
    width, height = declared_size(path)
    limit = max_pixels()
    if width * height > limit:
        raise ImageFileError(
            f"{path}: declares {width}x{height} = {width * height} pixels, more than the limit "
            f"of {limit} ({MAX_PIXELS_VARIABLE})"
        )
    if width == 0 or height == 0:
        raise ImageFileError(f"{path}: declares an empty {width}x{height} image")


def read_image(path: str | Path, flags: int = cv2.IMREAD_COLOR) -> np.ndarray:
    """The decoded image (``cv2.imread`` flags), after its declared size passed the limit."""
    _check_declared_size(path)
    try:
        image = cv2.imread(str(path), flags)
    except cv2.error as err:
        raise ImageFileError(f"{path}: cannot decode: {err.err}") from None
    if image is None:
        raise ImageFileError(f"{path}: cannot decode (damaged or truncated)")
    return image


def read_grid_image(path: str | Path, step: int) -> np.ndarray | Capture:
    """The BGR image of a file as perception on the grid of every ``step``-th pixel takes it.

    ``step`` 1: the full image. Else a :class:`Capture` whose grid image is the average of each
    ``step`` x ``step`` block: a JPEG decoded at that scale (``step`` 2, 4 or 8; the full image,
    or only its luma for the grey one, decoded when asked for), any other file decoded and
    area-averaged.
    """
    if step == 1:
        return read_image(path)
    _check_declared_size(path)
    try:
        data = Path(path).read_bytes()
    except OSError as err:
        raise ImageFileError(f"{path}: cannot read: {err.strerror}") from None
    if data.startswith(b"\xff\xd8") and step in REDUCED_FLAGS:
        grid = _decoded(decode_jpeg(data, step), path)
        return Capture(
            grid,
            step,
            "bgr",
            lambda: _decoded(decode_jpeg(data), path),
            lambda: _decoded(decode_jpeg_luma(data), path),
        )
    full = _decoded(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR), path)
    return Capture(area_grid(full, step), step, "bgr", lambda: full)


def _decoded(image: np.ndarray | None, path: str | Path) -> np.ndarray:
    if image is None:
        raise ImageFileError(f"{path}: cannot decode (damaged or truncated)")
    return image
