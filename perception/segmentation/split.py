"""Splitting foreground regions with the anchors' colour models (§4.2).

Every foreground pixel goes to the model ``j`` with the largest
``p_j(p) = M_j^Y(h(i_Y)) M_j^Cr(h(i_Cr)) M_j^Cb(h(i_Cb))``, or to "no model" when that is below
``t``; pixels of one class are then segmented again into connected pieces, the percepts.

Two choices keep this cheap and local. Only the models whose predicted box (grown by a margin)
overlaps a region compete for its pixels: a model on the other side of the image has nothing to
say about this region. And a region whose pixels all fall into one class (apart from fewer than
``min_pixels`` strays) is one percept as it is, with the histograms already computed for it; only
regions that really hold several classes are segmented again. Both steps are compiled loops
(:mod:`percept.perception.segmentation.split_kernels`), which a frame calls from its one compiled
call for the regions and their percepts (:mod:`.segment`).
"""

from __future__ import annotations

import numpy as np

from percept.perception.segmentation.labelling.regions import Regions
from percept.perception.segmentation.percepts import PerceptSet
from percept.perception.segmentation.split_kernels import split

NO_MODEL = 0
"""Pixel class of foreground that no model explains; model ``j`` is class ``j + 1``."""


def split_regions(
    regions: Regions, classes: np.ndarray, n_models: int, min_pixels: int
) -> PerceptSet:
    """Percepts from classified pixels: connected pieces (of at least ``min_pixels`` image
    pixels) of one class in each region that holds several; the other regions whole."""
    boxes, histograms, counts, rows = split(
        regions.boxes,
        regions.counts,
        regions.histograms,
        regions.offsets,
        regions.pixels,
        regions.pixel_bins,
        classes,
        n_models + 1,
        regions.labels.shape[1],
        regions.samples(min_pixels),
        regions.step,
    )
    return PerceptSet(boxes=boxes, histograms=histograms, counts=counts, regions=rows)
