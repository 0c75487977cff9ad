"""Frames at the size perception works on: JPEG decoded at a reduced scale, and a UVC camera's
raw YUYV turned straight into YCrCb on the grid.

Perception looks at every ``step``-th pixel of every ``step``-th row (its grid). Decoding a JPEG
at full size and then keeping a quarter of the pixels wastes most of the decode: libjpeg can
decode at 1/2, 1/4 or 1/8 scale directly (``cv2.IMREAD_REDUCED_COLOR_*``), each output pixel
the average of a ``step`` x ``step`` block. That is not the same image as picking every
``step``-th pixel (less noise, softer edges), so a background must be calibrated on the same kind
of frame it later classifies.

A raw YUYV frame (4:2:2, BT.601 limited range, as UVC cameras send it) holds for each pair of
pixels two lumas and one Cb, Cr. :func:`yuyv_to_ycrcb` takes the luma of each grid pixel and the
chroma of its pair, and stretches them to the full range of OpenCV's ``COLOR_BGR2YCrCb``, without
a BGR image in between.
"""

from __future__ import annotations

import cv2
import numpy as np

from percept.kinematics.camera import grid_shape

REDUCED_FLAGS = {
    2: cv2.IMREAD_REDUCED_COLOR_2,
    4: cv2.IMREAD_REDUCED_COLOR_4,
    8: cv2.IMREAD_REDUCED_COLOR_8,
}
"""``cv2.imdecode`` flags that decode a JPEG at 1/step scale, for the steps perception uses."""

# BT.601 limited range: luma 16..235, chroma 16..240 around 128. Full range: 0..255.
_Y_SCALE = 255.0 / 219.0
_C_SCALE = 255.0 / 224.0


def _range_tables() -> tuple[np.ndarray, np.ndarray]:
    """Look-up tables from limited-range luma and chroma codes to full-range ones."""
    codes = np.arange(256, dtype=np.float64)
    luma = np.clip(np.rint((codes - 16.0) * _Y_SCALE), 0, 255).astype(np.uint8)
    chroma = np.clip(np.rint((codes - 128.0) * _C_SCALE + 128.0), 0, 255).astype(np.uint8)
    return luma, chroma


_LUMA, _CHROMA = _range_tables()


def area_grid(image: np.ndarray, step: int) -> np.ndarray:
    """The image on the grid of ``step``, each grid pixel the average of its block (the kind of
    image a JPEG decoded at 1/step scale is), for images that cannot be decoded at that scale."""
    rows, columns = grid_shape(image.shape[1], image.shape[0], step)
    return cv2.resize(image, (columns, rows), interpolation=cv2.INTER_AREA)


def decode_jpeg(data: bytes | np.ndarray, step: int = 1) -> np.ndarray | None:
    """The BGR image of JPEG bytes at 1/``step`` scale (``step`` 1, 2, 4 or 8); None when the bytes
    do not decode."""
    flags = cv2.IMREAD_COLOR if step == 1 else REDUCED_FLAGS[step]
    buffer = np.frombuffer(data, np.uint8) if isinstance(data, bytes) else data
    return cv2.imdecode(buffer, flags)


def decode_jpeg_luma(data: bytes) -> np.ndarray | None:
    """The full-size grey image of JPEG bytes: their luma, without the colour planes' decoding
    and conversion (1.1 ms at 640x480 where BGR and ``COLOR_BGR2GRAY`` take 3.7 ms); it differs
    from the grey of the BGR image by the round trip's rounding (a few pixels in 10 000); None
    when the bytes do not decode."""
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)


def yuyv_to_ycrcb(yuyv: np.ndarray, step: int = 1) -> np.ndarray:
    """The full-range YCrCb image (as ``COLOR_BGR2YCrCb`` gives) of the grid of every ``step``-th
    pixel of a limited-range YUYV frame.

    ``yuyv`` is (H, W, 2) uint8 as OpenCV delivers it with ``CAP_PROP_CONVERT_RGB`` 0: channel 0
    the luma of each pixel, channel 1 Cb at even columns and Cr at odd ones. Each grid pixel takes
    its own luma and the Cb, Cr of its pair (no interpolation of chroma).
    """
    if yuyv.ndim != 3 or yuyv.shape[2] != 2 or yuyv.shape[1] % 2 or yuyv.dtype != np.uint8:
        raise ValueError(
            f"expected (H, W, 2) uint8 YUYV with W even, got {yuyv.shape} {yuyv.dtype}"
        )
    rows = yuyv[::step]
    columns = np.arange(0, yuyv.shape[1], step)
    pair = columns - columns % 2  # the pair's first column: its Cb; the next one: its Cr
    out = np.empty((rows.shape[0], columns.size, 3), np.uint8)
    out[..., 0] = _LUMA[rows[:, columns, 0]]
    out[..., 1] = _CHROMA[rows[:, pair + 1, 1]]
    out[..., 2] = _CHROMA[rows[:, pair, 1]]
    return out


def yuyv_luma(yuyv: np.ndarray) -> np.ndarray:
    """The full-size grey image of a limited-range YUYV frame: its luma stretched to the full
    range, as ``COLOR_BGR2GRAY`` of its BGR image gives it to rounding."""
    return _LUMA[yuyv[..., 0]]


def yuyv_to_bgr(yuyv: np.ndarray) -> np.ndarray:
    """The full-size BGR image of a YUYV frame, for what needs BGR (markers, viewers)."""
    return cv2.cvtColor(yuyv, cv2.COLOR_YUV2BGR_YUYV)
