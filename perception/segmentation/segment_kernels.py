"""A frame's segmentation in one compiled call: the regions of its foreground
(:mod:`.labelling.regions_kernels`), the colour split's classes of their pixels and the pieces of
the regions that hold several (:mod:`.split_kernels`), in the order of the data flow.

Called one by one from Python the three kernels cost, at 176x144, about as much again in their
calls, the many small arrays each returns and the records built between them. Each kernel keeps
its own module, tests and arithmetic: the results are those of the calls one by one, to the bit.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.segmentation.labelling.regions_kernels import label_regions
from percept.perception.segmentation.split_kernels import classify, split


@jit
def segment(
    mask: np.ndarray,
    ycc: np.ndarray,
    min_pixels: int,
    shift: int,
    m: int,
    joint: bool,
    step: int,
    model_boxes: np.ndarray,
    models: np.ndarray,
    threshold: float,
    margin: float,
    min_split: int,
) -> tuple[np.ndarray, ...]:
    """The regions of the 0/1 ``mask`` and their percepts: ``(labels, label_ids, boxes, counts,
    offsets, pixels, pixel_region, pixel_bins, histograms)`` as :func:`.label_regions` gives them
    (its arguments the first seven), then each region pixel's class and ``(boxes, histograms,
    counts, regions)`` of the percepts.

    With models (``model_boxes`` (n, 4), histograms ``models`` of the regions' shape; n > 0)
    the pixels are classified (:func:`.classify` with ``threshold`` and ``margin``) and the
    regions cut by class into pieces of at least ``min_split`` grid pixels (:func:`.split`);
    without, every pixel is of no model and every region one percept.
    """
    regions = label_regions(mask, ycc, min_pixels, shift, m, joint, step)
    boxes, counts, offsets, pixels, pixel_bins, histograms = (
        regions[2],
        regions[3],
        regions[4],
        regions[5],
        regions[7],
        regions[8],
    )
    n_models = model_boxes.shape[0]
    if n_models == 0:
        classes = np.zeros(offsets[-1], np.intp)
        percepts = (boxes.astype(np.float64), histograms, counts, np.arange(boxes.shape[0]))
    else:
        classes = classify(boxes, offsets, pixel_bins, model_boxes, models, threshold, margin)
        width = mask.shape[1]
        percepts = split(
            boxes,
            counts,
            histograms,
            offsets,
            pixels,
            pixel_bins,
            classes,
            n_models + 1,
            width,
            min_split,
            step,
        )
    return (*regions, classes, *percepts)
