"""Photometric compensation: each frame mapped back to the light of the calibration.

A change of light or exposure scales every colour; in YCrCb that scales Y and the chroma's
distance from grey (128), and a change of white balance or black level adds an offset. So per
channel ``c``, with centre ``C`` (0 for Y, 128 for Cr and Cb)::

    observed_c - C = gain_c * (expected_c - C) + offset_c

is fitted on pixels that are background with confidence (``expected``: the model's mean) by least
squares, starting from the median ratio of Y and trimming outliers (objects and people the mask
missed) twice (compiled: :mod:`.photometric_kernels`). Where the model's
values of a channel spread too little to tell a gain from an offset (a plain floor), Y takes a pure
gain (what light does) and the chroma the gain of Y with an offset of their own.

The light changes slowly but for its sudden changes, so a frame is fitted only when the
photometry in use no longer holds on its samples (:data:`HOLD`): the test is one pass over them,
a fit some twenty. A switch or an exposure step moves every sample far beyond that and is
fitted in the frame it happens in; drift is fitted once it adds up to :data:`HOLD`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from percept.perception.light.photometry.photometric_kernels import affine_map, fit_photometry

CENTRE = np.array([0.0, 128.0, 128.0])
"""The value of each channel (Y, Cr, Cb) that a change of light leaves in place."""
MIN_SPREAD = 12.0
"""Grey levels: the model's values of a channel must spread this much (standard deviation)
for its gain and offset to be fitted together."""


HOLD = 0.05
"""Grey levels: the photometry in use holds while the residuals of the samples it keeps average
within this of 0, as a whole and over a deviation of each channel's values (a gain off). The
mean of 600 samples' noise varies by about a tenth of a grey level; the foreground test's bounds
are several grey levels wide. Yet the real videos tell holds of a tenth from fits: TUD-Stadtmitte
(people walking through most of the view) tracks at MOTA -1.139 with 0.25, -1.028 with 0.1, and
-0.936 with 0.05, as when fitting every frame (TUD-Campus -0.668, -0.668, -0.652). At 0.05 the
photometry holds in a sixth of TUD-Stadtmitte's frames and few of the rendered ones, so this
saves little time; at 0.25 it held in 199 of 200 frames of the speed benchmark's scene."""


def _identity() -> np.ndarray:
    """The identity's (4, 3) array of :attr:`Photometry.fitted`."""
    fitted = np.zeros((4, 3))
    fitted[0] = 1.0
    return fitted


@dataclass(frozen=True)
class Photometry:
    """How a frame's colours relate to the calibration's: per channel Y, Cr, Cb."""

    gain: tuple[float, float, float] = (1.0, 1.0, 1.0)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inliers: int = 0
    """Pixels the fit kept (0: nothing was fitted, the identity)."""
    fitted: np.ndarray = field(default_factory=_identity, repr=False, compare=False)
    """The fit as the kernel keeps it (4, 3): gain, offset, robust deviation of the residuals
    per channel, share of the samples kept (first column)."""

    @classmethod
    def of(cls, fitted: np.ndarray, inliers: int) -> Photometry:
        """The photometry of the kernel's ``fitted`` array, on ``inliers`` samples."""
        g, o = fitted[0].tolist(), fitted[1].tolist()
        return cls((g[0], g[1], g[2]), (o[0], o[1], o[2]), inliers, fitted)

    @cached_property
    def matrix(self) -> np.ndarray:
        """The 3x4 affine map of a frame's YCrCb values to the calibration's light, for
        ``cv2.transform``: ``expected = (observed - C - offset) / gain + C`` (a lookup table
        per channel, ``cv2.LUT``, took four times as long). Frames are mapped in the one pass
        of :mod:`percept.perception.light.foreground`, which computes it as ``cv2.transform``
        does (compiled: :func:`.photometric_kernels.affine_map`)."""
        return affine_map(np.array(self.gain), np.array(self.offset), CENTRE)


IDENTITY = Photometry()


def fit(
    ycc: np.ndarray,
    expected: np.ndarray,
    excluded: np.ndarray,
    previous: np.ndarray,
    step: int = 1,
    current: Photometry = IDENTITY,
    min_share: float = 0.0,
    min_inliers: float = 0.0,
) -> Photometry:
    """The gain and offset of each channel mapping ``expected`` (float32 (H', W', 3), the
    values of the grid's pixels: :func:`on_grid`) to ``ycc`` (uint8 (H, W, 3)), robust to a
    minority of outliers, on the grid of ``step`` outside
    ``excluded`` (bool (H, W)) and the foreground ``previous`` (uint8 (H, W)); the identity when
    there are fewer than 8 samples. ``current`` (the photometry in use) is kept while it holds
    (:data:`HOLD`), when the samples are fewer than ``min_share`` of the grid, or when the fit
    keeps fewer than ``min_inliers`` of them."""
    fitted, inliers = fit_photometry(
        ycc,
        expected,
        excluded,
        previous,
        step,
        current.fitted,
        min_share,
        min_inliers,
        CENTRE,
        MIN_SPREAD,
        HOLD,
    )
    return after_fit(current, fitted, inliers)


def after_fit(current: Photometry, fitted: np.ndarray, inliers: int) -> Photometry:
    """The photometry in use after a fit that gave ``fitted`` (gains and offsets, as
    ``fit_photometry`` returns them) on ``inliers`` samples: ``current`` kept (-1), the identity
    (0), or the fitted one."""
    if inliers < 0:
        return current
    return IDENTITY if inliers == 0 else Photometry.of(fitted, inliers)


def sample_step(shape: tuple[int, int], samples: int) -> int:
    """Step of the sparse grid (every s-th pixel of every s-th row) holding about ``samples``
    pixels of an image of ``shape``."""
    return max(1, int(np.sqrt(shape[0] * shape[1] / max(samples, 1))))


def on_grid(values: np.ndarray, step: int) -> np.ndarray:
    """The pixels of ``values`` (H, W, 3) on the sparse grid of ``step``, contiguous: the
    ``expected`` of :func:`fit`."""
    return np.ascontiguousarray(values[::step, ::step])
