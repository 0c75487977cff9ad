"""A frame's foreground in the light of a session: the frame mapped to the calibration's light,
the foreground test on the model, and shadows dropped, in one compiled pass over the pixels
(:mod:`percept.perception.light.foreground_kernels`; as three passes, ``cv2.transform``,
``cv2.inRange`` and a kernel, it took half as long again).

Shadows: darker in Y, the chroma kept. A shadow takes light away from a surface: its Y falls to
a fraction ``r`` of the background's and its chroma's distance from grey scales by the same
``r``, so the chroma barely moves. A pixel is shadow when ``darkest <= r < 1`` and Cr, Cb lie
within ``chroma`` deviations (``max(sigma, sigma_min)``) of ``128 + r (mu - 128)``. A dark
object of the background's hue passes that test too; ``darkest`` keeps the darkest of them
foreground.

Where the background is (nearly) grey, so is its shadow, and a grey object there (a dark car on
a road, a grey barrel on a grey table, a person in dark clothes) would pass the test as well:
the chroma cannot tell them apart. A pixel is taken for shadow only where it can, that is where a
grey surface's chroma (128) lies outside the bounds around the shadow's. On CDnet highway
(grey road) the test without that condition took 40 car pixels for each shadow pixel; with it
the grey road's pixels stay foreground, shadow or not.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from percept.perception.light.foreground_kernels import light_foreground
from percept.perception.light.photometry.photometric import Photometry
from percept.perception.params import LightParams
from percept.perception.segmentation.background import BackgroundModel


def foreground(
    ycc: np.ndarray, photometry: Photometry, model: BackgroundModel, params: LightParams
) -> tuple[np.ndarray, np.ndarray]:
    """``ycc`` (uint8 YCrCb, C-contiguous, of the model's size) in the calibration's light, as
    ``cv2.transform`` maps it with the photometry's matrix (``ycc`` itself for the identity),
    and its 0/1 foreground on ``model`` (uint8, before noise reduction), shadows dropped when
    ``params.shadows``."""
    shadows = (model.mean, model.sigma, model.params.sigma_min) if params.shadows else None
    return _one_pass(ycc, photometry, model.lower, model.upper, shadows, params)


def view_foreground(
    ycc: np.ndarray, photometry: Photometry, lower: np.ndarray, upper: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`foreground` for a frame of the moving head, whose background bounds ``lower``
    and ``upper`` (uint8 (H, W, 3)) are those of its view: no shadow test, as the view keeps no
    mean and deviation per pixel."""
    return _one_pass(ycc, photometry, lower, upper, None, None)


NO_SHADOWS = np.zeros((1, 1, 3), np.float32)
"""The mean and deviation the pass takes when it tests no shadows (and reads neither)."""


def _one_pass(
    ycc: np.ndarray,
    photometry: Photometry,
    lower: np.ndarray,
    upper: np.ndarray,
    shadows: tuple[np.ndarray, np.ndarray, float] | None,
    params: LightParams | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The compiled pass: the frame mapped, tested on ``lower``/``upper``, and tested for
    shadows on ``shadows`` (mean, sigma, sigma_min) with ``params``' thresholds when given."""
    compensated = photometry.inliers != 0
    frame = np.empty_like(ycc) if compensated else ycc
    raw = np.empty(ycc.shape[:2], np.uint8)
    mean, sigma, sigma_min = (NO_SHADOWS, NO_SHADOWS, 0.0) if shadows is None else shadows
    light_foreground(
        ycc,
        photometry.matrix.astype(np.float32),
        compensated,
        opencv_fuses(),
        lower,
        upper,
        mean,
        sigma,
        sigma_min,
        shadows is not None,
        0.0 if params is None else params.shadow_darkest,
        0.0 if params is None else params.shadow_chroma,
        frame,
        raw,
    )
    return frame, raw


FUSE_PROBE = (np.float32(1.4554425477981567), np.float32(-122.16297149658203), 131)
"""A gain, offset and grey level whose map is 68 with the product and sum rounded once, 69 with
each rounded."""


@functools.cache
def opencv_fuses() -> bool:
    """Whether this machine's OpenCV maps a grey level (``cv2.transform``) with the product and
    sum rounded once, as its code for CPUs with fused multiply-add does, or twice, as its code
    for older CPUs does: the compiled pass does the same, so that a frame it maps is the one
    ``cv2.transform`` maps here."""
    gain, offset, level = FUSE_PROBE
    matrix = np.array(
        [[gain, 0, 0, offset], [0, gain, 0, offset], [0, 0, gain, offset]], np.float32
    )
    return int(cv2.transform(np.full((1, 1, 3), level, np.uint8), matrix)[0, 0, 0]) == 68
