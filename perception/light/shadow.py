"""Shadows: darker in Y, the chroma kept.

A shadow takes light away from a surface: its Y falls to a fraction ``r`` of the background's
and its chroma's distance from grey scales by the same ``r``, so the chroma barely moves. A pixel
is shadow when ``darkest <= r < 1`` and Cr, Cb lie within ``chroma`` deviations
(``max(sigma, sigma_min)``) of ``128 + r (mu - 128)``. A dark object of the background's hue
passes that test too; ``darkest`` keeps the darkest of them foreground.

Where the background is (nearly) grey, so is its shadow, and a grey object there (a dark car on
a road, a grey barrel on a grey table, a person in dark clothes) would pass the test as well:
the chroma cannot tell them apart. A pixel is taken for shadow only where it can, that is where a
grey surface's chroma (128) lies outside the bounds around the shadow's. On CDnet highway
(grey road) the test without that condition took 40 car pixels for each shadow pixel; with it
the grey road's pixels stay foreground, shadow or not.
"""

from __future__ import annotations

import numpy as np

from percept.perception.background import BackgroundModel
from percept.perception.kernels.light.shadow import clear_shadows


def clear_shadow(
    raw: np.ndarray, ycc: np.ndarray, model: BackgroundModel, darkest: float, chroma: float
) -> None:
    """Set to 0 the pixels of the foreground ``raw`` ((H, W) uint8 of the model's size) that are
    shadow in ``ycc`` (uint8 YCrCb) on ``model`` (compiled:
    :func:`percept.perception.kernels.light.shadow.clear_shadows`)."""
    clear_shadows(raw, ycc, model.mean, model.sigma, model.params.sigma_min, darkest, chroma)
