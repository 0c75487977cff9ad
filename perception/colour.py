"""Colour: YCrCb images, the histograms of colour models, and colours for drawing.

A colour model is a product of normalised histograms, its *factors*, each summing to 1. The bin
of intensity ``i`` is ``h(i) = i * m // 256``; for every bin to cover the same range of the 256
intensities ``m`` divides 256, so ``h`` is a right shift. Two models (:class:`Coding`):

- ``marginals``, the chapter's: arrays ``(..., 3, m)``, one histogram for each of Y, Cr and Cb
  (that order); a pixel's probability is ``M^Y(h(Y)) M^Cr(h(Cr)) M^Cb(h(Cb))``;
- ``joint_chroma``: arrays ``(..., 2, m * m)``, the histogram of Y (in the first ``m`` bins) and
  the joint histogram of Cr and Cb (bin ``h(Cr) m + h(Cb)``); a pixel's probability is
  ``M^Y(h(Y)) M^CrCb(h(Cr), h(Cb))``. The product of the Cr and Cb marginals also explains the
  colours between those a model learnt (an orange model with its lit and shaded faces scores a
  yellow neighbour well); the joint histogram explains only the colours seen.

Both keep the product's scale: a uniform model gives ``1 / m^3`` in each. The histograms are
counted by the compiled kernels of the regions and the colour split (a pixel's bins:
:func:`~.colour_kernels.codes`) and compared (Bhattacharyya coefficient, the product over the
factors) in the association.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from percept.perception.colour_kernels import histograms_of
from percept.perception.params import ColourModel

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


@dataclass(frozen=True)
class Coding:
    """How pixels are counted into the histograms of a colour model: ``m`` bins per channel,
    and whether Cr and Cb are counted together (``joint_chroma``) or apart (``marginals``)."""

    m: int
    joint: bool

    def __post_init__(self) -> None:
        bin_shift(self.m)  # m must divide the 256 intensities

    @staticmethod
    def of(model: ColourModel, m: int) -> Coding:
        return Coding(m, model == "joint_chroma")

    @staticmethod
    def of_histograms(histograms: np.ndarray) -> Coding:
        """The coding of histograms (..., 3, m) or (..., 2, m * m), told by their shape."""
        factors, width = histograms.shape[-2:]
        if factors == 3:
            return Coding(width, False)
        m = math.isqrt(width)
        if factors != 2 or m * m != width:
            raise ValueError(f"histograms of shape {histograms.shape} are of no colour model")
        return Coding(m, True)

    @property
    def shift(self) -> int:
        return bin_shift(self.m)

    @property
    def shape(self) -> tuple[int, int]:
        """(factors, bins of each) of one colour model."""
        return (2, self.m * self.m) if self.joint else (3, self.m)

    def histograms(self, ycc: np.ndarray) -> np.ndarray:
        """The colour model (factors, bins) of YCrCb pixels ``ycc`` (k, 3) uint8, k > 0."""
        return histograms_of(np.ascontiguousarray(ycc), self.shift, self.m, self.joint)

    def marginals(self, histograms: np.ndarray) -> np.ndarray:
        """The Y, Cr and Cb histograms (..., 3, m) of colour models of this coding: with the
        joint chroma, Y from the first ``m`` bins and the Cr and Cb marginals of the joint
        histogram (bin ``h(Cr) m + h(Cb)``)."""
        h = np.asarray(histograms, dtype=float)
        if not self.joint:
            return h
        joint = h[..., 1, :].reshape(*h.shape[:-2], self.m, self.m)
        return np.stack([h[..., 0, : self.m], joint.sum(axis=-1), joint.sum(axis=-2)], axis=-2)


def histogram_means(histograms: np.ndarray) -> np.ndarray:
    """Mean Y, Cr, Cb (..., 3) of colour models on the 0..255 scale: of the histograms
    (..., 3, m) of each (normalised or not), or of their marginals where they hold the joint
    chroma (..., 2, m * m) (:meth:`Coding.marginals`); bin k of m stands for its centre
    ``(k + 0.5) * 256 / m``."""
    h = np.asarray(histograms, dtype=float)
    if h.shape[-2] == 2:
        h = Coding.of_histograms(h).marginals(h)
    totals = h.sum(axis=-1)
    if not (totals > 0).all():
        raise ValueError("every histogram needs some mass")
    return (h @ _bin_centres(h.shape[-1])) / totals


@functools.cache
def _bin_centres(m: int) -> np.ndarray:
    """The centres of m bins on the 0..255 scale (read only: shared by every call)."""
    centres = (np.arange(m) + 0.5) * (256.0 / m)
    centres.flags.writeable = False
    return centres


def hue(histograms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hue (radians) and chroma (grey levels) of the mean colour of histograms: the
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
