"""A frame's regions and percepts (§4.1-4.2) in one compiled call
(:func:`percept.perception.segmentation.segment_kernels.segment`): the regions of its foreground,
then, when the anchors' colour models are given, each region pixel's class and the regions cut
into pieces of one class; without models every region is one percept. The results are those of
:func:`~.regions.find_regions` and :func:`~.split.split_regions` with the classes of
:func:`~.split_kernels.classify`, to the bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from percept.perception.colour import bin_shift
from percept.perception.params import RegionParams, SplitParams
from percept.perception.segmentation.percepts import PerceptSet
from percept.perception.segmentation.regions import Regions, grid_samples, regions_of
from percept.perception.segmentation.segment_kernels import segment


@dataclass(frozen=True)
class Segmentation:
    """What :func:`segment_frame` gives: the regions, their percepts and each pixel's class."""

    regions: Regions
    percepts: PerceptSet
    classes: np.ndarray
    """Class of each of ``regions.pixels``: 0 no model, j + 1 model j."""


def segment_frame(
    fg: np.ndarray,
    ycc: np.ndarray,
    regions: RegionParams,
    min_region_pixels: int,
    split: SplitParams,
    min_split_pixels: int,
    step: int,
    model_boxes: np.ndarray,
    models: np.ndarray,
) -> Segmentation:
    """The regions of the 0/1 foreground ``fg`` (the grid of every ``step``-th pixel; ``ycc``
    its YCrCb image) of at least ``min_region_pixels`` image pixels, and their percepts, split by
    the colour models ``model_boxes`` (n, 4) and histograms ``models`` (n, 3, m) into pieces of at
    least ``min_split_pixels`` (n = 0: not split)."""
    m = regions.bins
    out = segment(
        np.ascontiguousarray(fg),
        ycc,
        grid_samples(min_region_pixels, step),
        bin_shift(m),
        m,
        step,
        model_boxes,
        models,
        float(split.threshold),
        float(split.margin),
        grid_samples(min_split_pixels, step),
    )
    boxes, histograms, counts, rows = out[10:]
    return Segmentation(
        regions=regions_of(out[:9], step),
        percepts=PerceptSet(boxes=boxes, histograms=histograms, counts=counts, regions=rows),
        classes=out[9],
    )
