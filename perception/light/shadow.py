"""Shadows: darker in Y, the chroma kept.

A shadow takes light away from a surface: its Y falls to a fraction ``r`` of the background's
and its chroma's distance from grey scales by the same ``r``, so the chroma barely moves. A pixel
is shadow when ``darkest <= r < 1`` and Cr, Cb lie within ``chroma`` deviations
(``max(sigma, sigma_min)``) of ``128 + r (mu - 128)``. A dark object of the background's hue
passes that test too; ``darkest`` keeps the darkest of them foreground.
"""

from __future__ import annotations

import numpy as np

from percept.perception.background import BackgroundModel


def shadow_mask(
    ycc: np.ndarray, model: BackgroundModel, darkest: float, chroma: float, where: np.ndarray
) -> np.ndarray:
    """Which of the pixels ``where`` (flat indices into (H, W)) of ``ycc`` (uint8 YCrCb of the
    model's size) are shadow on ``model``, as bool (n,)."""
    pixels = ycc.reshape(-1, 3)[where].astype(np.float32)
    mean = model.mean.reshape(-1, 3)[where]
    ratio = pixels[:, 0] / np.maximum(mean[:, 0], 1.0)
    sigma = model.sigma.reshape(-1, 3)[where, 1:]
    tolerance = chroma * np.maximum(sigma, model.params.sigma_min)
    expected = 128.0 + ratio[:, None] * (mean[:, 1:] - 128.0)
    kept = np.abs(pixels[:, 1:] - expected) <= tolerance
    return (ratio >= darkest) & (ratio < 1.0) & kept[:, 0] & kept[:, 1]
