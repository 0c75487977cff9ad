"""Colour: YCrCb images, the bins of m-bin histograms per channel, and colours for drawing.

Histograms are arrays of shape ``(..., 3, m)``: one normalised histogram for each of Y, Cr and Cb
(that order), each summing to 1. The bin of intensity ``i`` is ``h(i) = i * m // 256``; for every
bin to cover the same range of the 256 intensities ``m`` divides 256, so ``h`` is a right shift.
The histograms themselves are counted by the compiled kernels of the regions and the colour split
(:mod:`percept.perception.compiled`), and compared (Bhattacharyya coefficient) in the association.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from percept.perception.features.experience import histogram_means

CHANNELS = ("Y", "Cr", "Cb")


_LUMA = np.array([0.114, 0.587, 0.299])  # B, G, R weights of Y (ITU-R BT.601)
_BGR_TO_YCRCB = np.array(
    [
        [*_LUMA, 0.0],
        [*(0.713 * (np.array([0.0, 0.0, 1.0]) - _LUMA)), 128.0],  # Cr = 0.713 (R - Y) + 128
        [*(0.564 * (np.array([1.0, 0.0, 0.0]) - _LUMA)), 128.0],  # Cb = 0.564 (B - Y) + 128
    ],
    np.float32,
)


def to_ycrcb(frame_bgr: np.ndarray) -> np.ndarray:
    """The 8-bit YCrCb image of an 8-bit BGR image (OpenCV's ``COLOR_BGR2YCrCb`` coefficients).

    One matrix product per pixel: a third faster than ``cv2.cvtColor``, whose fixed-point
    arithmetic rounds differently (Cr and Cb differ by one grey level for some colours).
    """
    return cv2.transform(frame_bgr, _BGR_TO_YCRCB)


def bin_shift(m: int) -> int:
    """``h(i) = i >> bin_shift(m)`` for ``m`` (a power of two, at most 256) bins."""
    if m < 1 or m > 256 or m & (m - 1):
        raise ValueError(f"{m} bins do not split 256 intensities evenly")
    return 8 - (m.bit_length() - 1)


def hue(histograms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hue (radians) and chroma (grey levels) of the mean colour of histograms (..., 3, m): the
    angle and length of its (Cr - 128, Cb - 128). Under white light a shade of a colour (the
    same surface lit more or less) keeps its hue: Cr - 128 and Cb - 128 scale together."""
    means = histogram_means(histograms) - 128.0
    cr, cb = means[..., 1], means[..., 2]
    return np.arctan2(cb, cr), np.hypot(cr, cb)


def feature_bgr(y: float | None, cr: float | None, cb: float | None) -> tuple[int, int, int] | None:
    """The colour (BGR, 0..255) of an object's colour features, the means of its Y, Cr and Cb
    histograms; None when one is unknown. For drawing: a picture's mean colour, not a pixel's."""
    if y is None or cr is None or cb is None:
        return None
    return ycrcb_bgr((y, cr, cb))


def ycrcb_bgr(ycc: Sequence[float] | np.ndarray) -> tuple[int, int, int]:
    """The BGR triple (0..255) of one Y, Cr, Cb colour, each clipped to 0..255."""
    pixel = np.clip(np.asarray(ycc, dtype=float), 0, 255).astype(np.uint8).reshape(1, 1, 3)
    b, g, r = cv2.cvtColor(pixel, cv2.COLOR_YCrCb2BGR)[0, 0]
    return int(b), int(g), int(r)
