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
from percept.perception.kernels.shadow import clear_shadows


def clear_shadow(
    raw: np.ndarray, ycc: np.ndarray, model: BackgroundModel, darkest: float, chroma: float
) -> None:
    """Set to 0 the pixels of the foreground ``raw`` ((H, W) uint8 of the model's size) that are
    shadow in ``ycc`` (uint8 YCrCb) on ``model`` (compiled:
    :func:`percept.perception.kernels.shadow.clear_shadows`)."""
    clear_shadows(raw, ycc, model.mean, model.sigma, model.params.sigma_min, darkest, chroma)
