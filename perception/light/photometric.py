"""Photometric compensation: each frame mapped back to the light of the calibration.

A change of light or exposure scales every colour; in YCrCb that scales Y and the chroma's
distance from grey (128), and a change of white balance or black level adds an offset. So per
channel ``c``, with centre ``C`` (0 for Y, 128 for Cr and Cb)::

    observed_c - C = gain_c * (expected_c - C) + offset_c

is fitted on pixels that are background with confidence (``expected``: the model's mean) by
least squares, starting from the median ratio of Y and trimming outliers (objects and people
the mask missed) twice (compiled: :mod:`percept.perception.kernels.photometric`). Where the model's
values of a channel spread too little to tell a gain from an offset (a plain floor), Y takes a
pure gain (what light does) and the chroma the gain of Y with an offset of their own.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from percept.perception.kernels.photometric import fit_photometry

CENTRE = np.array([0.0, 128.0, 128.0])
"""The value of each channel (Y, Cr, Cb) that a change of light leaves in place."""
MIN_SPREAD = 12.0
"""Grey levels: the model's values of a channel must spread this much (standard deviation)
for its gain and offset to be fitted together."""


@dataclass(frozen=True)
class Photometry:
    """How a frame's colours relate to the calibration's: per channel Y, Cr, Cb."""

    gain: tuple[float, float, float] = (1.0, 1.0, 1.0)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inliers: int = 0
    """Pixels the fit kept (0: nothing was fitted, the identity)."""

    def matrix(self) -> np.ndarray:
        """The 3x4 affine map of a frame's YCrCb values to the calibration's light, for
        ``cv2.transform``: ``expected = (observed - C - offset) / gain + C``."""
        g = np.asarray(self.gain)
        shift = CENTRE - (CENTRE + np.asarray(self.offset)) / g
        return np.concatenate([np.diag(1.0 / g), shift[:, None]], axis=1)


IDENTITY = Photometry()


def fit(observed: np.ndarray, expected: np.ndarray) -> Photometry:
    """The gain and offset of each channel mapping ``expected`` to ``observed`` ((n, 3) each),
    robust to a minority of outliers; the identity when there are fewer than 8 samples."""
    gain, offset, inliers = fit_photometry(
        np.ascontiguousarray(observed), np.ascontiguousarray(expected), CENTRE, MIN_SPREAD
    )
    if inliers == 0:
        return IDENTITY
    return Photometry(
        gain=(float(gain[0]), float(gain[1]), float(gain[2])),
        offset=(float(offset[0]), float(offset[1]), float(offset[2])),
        inliers=int(inliers),
    )


def compensate(ycc: np.ndarray, photometry: Photometry) -> np.ndarray:
    """``ycc`` (uint8 YCrCb) as it would look in the calibration's light (rounded, clipped)."""
    if photometry.inliers == 0:
        return ycc
    return cv2.transform(ycc, photometry.matrix())


def sample_step(shape: tuple[int, int], samples: int) -> int:
    """Step of the sparse grid (every s-th pixel of every s-th row) holding about ``samples``
    pixels of an image of ``shape``."""
    return max(1, int(np.sqrt(shape[0] * shape[1] / max(samples, 1))))
