"""Colour: YCrCb images, m-bin histograms per channel, and the Bhattacharyya coefficient.

Histograms are arrays of shape ``(..., 3, m)``: one normalised histogram for each of Y, Cr and Cb
(that order), each summing to 1. The bin of intensity ``i`` is ``h(i) = i * m // 256``, so every
bin covers the same range of intensities. The joint bin of a pixel,
``(h(Y) * m + h(Cr)) * m + h(Cb)``, indexes tables of ``m**3`` entries, which lets a colour model
be evaluated for many pixels with one lookup.
"""

from __future__ import annotations

import cv2
import numpy as np

CHANNELS = ("Y", "Cr", "Cb")
_CHANNEL = np.arange(3)


def to_ycrcb(frame_bgr: np.ndarray) -> np.ndarray:
    """The 8-bit YCrCb image of an 8-bit BGR image."""
    return cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2YCrCb)


def bin_table(m: int) -> np.ndarray:
    """``h``: the bin (0..m-1) of each intensity 0..255, as a lookup table."""
    return (np.arange(256) * m // 256).astype(np.uint8)


def joint_bins(bins: np.ndarray, m: int) -> np.ndarray:
    """Joint bin index (0..m**3-1) from per-channel bins of shape ``(n, 3)``."""
    b = bins.astype(np.intp)
    return (b[:, 0] * m + b[:, 1]) * m + b[:, 2]


def grouped_histograms(groups: np.ndarray, bins: np.ndarray, n: int, m: int) -> np.ndarray:
    """Normalised histograms ``(n, 3, m)`` of the pixels of each group 0..n-1.

    ``groups`` holds each pixel's group, ``bins`` its per-channel bins ``(pixels, 3)``. A group
    without pixels gets all-zero histograms. One ``bincount`` does all groups and channels.
    """
    keys = (groups[:, None] * 3 + _CHANNEL) * m + bins
    counts = np.bincount(keys.ravel(), minlength=n * 3 * m).reshape(n, 3, m)
    return counts / np.maximum(counts[:, 0].sum(axis=1), 1)[:, None, None]


def bhattacharyya(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``BC(M, M') = sum_k sqrt(M(k) M'(k))`` over the last axis (1 for equal histograms)."""
    return np.sqrt(a * b).sum(axis=-1)


def colour_similarity(percepts: np.ndarray, models: np.ndarray) -> np.ndarray:
    """``prod_c BC(M_P^c, M_O^c)`` for every percept (``(k, 3, m)``) and model (``(n, 3, m)``).

    Returns a ``(k, n)`` matrix; the square roots are taken once so that the sums are matrix
    products.
    """
    sp, so = np.sqrt(percepts), np.sqrt(models)
    out = np.ones((len(percepts), len(models)))
    for c in range(3):
        out *= sp[:, c] @ so[:, c].T
    return out


def likelihood_table(models: np.ndarray) -> np.ndarray:
    """``p_j = M_j^Y(h_Y) M_j^Cr(h_Cr) M_j^Cb(h_Cb)`` for every joint bin: ``(n, m**3)``."""
    n, _, m = models.shape
    h = models.astype(np.float32)
    table = h[:, 0, :, None, None] * h[:, 1, None, :, None] * h[:, 2, None, None, :]
    return table.reshape(n, m**3)


def mean_colour(histograms: np.ndarray) -> np.ndarray:
    """Mean Y, Cr, Cb (0..255) of histograms ``(..., 3, m)``, taking each bin at its centre."""
    m = histograms.shape[-1]
    centres = (np.arange(m) + 0.5) * 256.0 / m
    return histograms @ centres
