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

from percept.perception.colour import Coding
from percept.perception.params import SplitParams
from percept.perception.segmentation.labelling.regions import Regions, grid_samples, regions_of
from percept.perception.segmentation.percepts import PerceptSet
from percept.perception.segmentation.segment_kernels import segment


@dataclass(frozen=True)
class Segmentation:
    """What :class:`Segmenter` gives for a frame: its regions, their percepts and each region
    pixel's class."""

    regions: Regions
    percepts: PerceptSet
    classes: np.ndarray
    """Class of each of ``regions.pixels``: 0 no model, j + 1 model j."""


class Segmenter:
    """Regions of at least ``min_region_pixels`` image pixels with the histograms of ``coding``,
    and their percepts cut by the colour split (``split``, pieces of at least
    ``min_split_pixels``), on the grid of every ``step``-th pixel: what is the same for every
    frame, worked out once."""

    def __init__(
        self,
        coding: Coding,
        min_region_pixels: int,
        split: SplitParams,
        min_split_pixels: int,
        step: int,
    ) -> None:
        self.coding, self.step = coding, step
        self.min_region = grid_samples(min_region_pixels, step)
        self.min_split = grid_samples(min_split_pixels, step)
        self.threshold, self.margin = float(split.threshold), float(split.margin)
        self.no_models = (np.zeros((0, 4)), np.zeros((0, *coding.shape)))
        """Boxes and histograms of no colour model: the regions are not split."""

    def __call__(
        self, fg: np.ndarray, ycc: np.ndarray, model_boxes: np.ndarray, models: np.ndarray
    ) -> Segmentation:
        """The regions of the 0/1 foreground ``fg`` (``ycc`` its YCrCb image, both on the grid)
        and their percepts, split by the colour models ``model_boxes`` (n, 4) and histograms
        ``models`` (n, factors, bins) (n = 0: not split; :attr:`no_models`)."""
        out = segment(
            np.ascontiguousarray(fg),
            ycc,
            self.min_region,
            self.coding.shift,
            self.coding.m,
            self.coding.joint,
            self.step,
            model_boxes,
            models,
            self.threshold,
            self.margin,
            self.min_split,
        )
        boxes, histograms, counts, rows = out[10:]
        return Segmentation(
            regions=regions_of(out[:9], self.step),
            percepts=PerceptSet(boxes=boxes, histograms=histograms, counts=counts, regions=rows),
            classes=out[9],
        )
