"""The ghost test of :mod:`percept.perception.light.maintenance` over the foreground's regions.

The regions are labelled by the regions' kernel
(:func:`percept.perception.segmentation.labelling.regions_kernels.label_regions`), which gives each
region's box and size on the way, inside the light's compiled call after the opening. OpenCV's
labelling alone is faster (31 against 47 µs on a frame of the busy scene at 176x144), but with
a pass over all its labels for the boxes, and the calls around it from Python, the ghost test took
137 µs where it takes 114 now. What is done per region
(its box clear of the anchors, its stillness, the ring of background around it and the mean
colours inside and around, in the frame and in the model) is one pass over each region's box
here, where it took some twenty numpy and OpenCV calls per region.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.segmentation.labelling.regions_kernels import label_regions

STILL = 0.01
"""Share of a region's pixels that may differ from the last frame for it to be still."""
FED = 16
"""Pixels of a region near an anchor that are tested at any size: below a new anchor's
smallest, a ghost still feeds the anchor born on it."""
UNSETTLED = 0.1
"""Share of a region near an anchor that may be foreground for less than the hold time."""


@jit
def ghost_regions(
    fg: np.ndarray,
    ycc: np.ndarray,
    mean: np.ndarray,
    anchored: np.ndarray,
    settled: np.ndarray,
    previous: np.ndarray,
    moving: np.ndarray,
    min_pixels: int,
    match: float,
    ring: int,
) -> tuple[np.ndarray, int]:
    """Bool (H, W) and how many there are: the 8-connected regions of ``fg`` (0/1 uint8 (H, W),
    C-contiguous) that are ghosts: at least ``min_pixels``, still against
    ``previous`` (their pixels differing by more than ``moving`` in a channel at most
    :data:`STILL` of them), at least
    ``ring`` pixels of background (``fg`` 0) within ``ring`` of them, and the model's ``mean``
    inside at least ``2 match`` from its mean around while the frame ``ycc`` inside is within
    ``max(match, that / 4)`` of the frame around (distances of mean colours).

    A region with an ``anchored`` pixel within ``ring`` of its box is tested from :data:`FED`
    pixels on, and only once all but :data:`UNSETTLED` of it is ``settled`` (foreground for a
    while): an anchor may have been born on a ghost while it still moved, as someone who stood
    there during calibration walked off, but a body the colour of the floor passing over
    something learned in (an arm over a marker box's edge) looks like a ghost for a moment."""
    height, width = fg.shape
    out = np.zeros((height, width), np.bool_)
    found = 0
    # The regions of FED pixels or more (smaller ones are never tested), their boxes and sizes;
    # no histograms (a single bin), which the test does not use.
    labelled = label_regions(fg, ycc, min(min_pixels, FED), 8, 1, False, 1)
    labels, label_ids, boxes, counts = labelled[0], labelled[1], labelled[2], labelled[3]
    for r in range(label_ids.shape[0]):
        i = label_ids[r]
        left, top, w, h, area = boxes[r, 0], boxes[r, 1], boxes[r, 2], boxes[r, 3], counts[r]
        x0, y0 = max(left - ring, 0), max(top - ring, 0)
        x1, y1 = min(left + w + ring, width), min(top + h + ring, height)
        near_anchor = _any(anchored, y0, y1, x0, x1)
        if area < min_pixels and not near_anchor:
            continue
        moved = unsettled = 0
        for v in range(top, top + h):
            for u in range(left, left + w):
                if labels[v, u] != i:
                    continue
                if not settled[v, u]:
                    unsettled += 1
                for c in range(3):
                    if abs(np.int32(ycc[v, u, c]) - np.int32(previous[v, u, c])) > moving[v, u, c]:
                        moved += 1
                        break
        if moved > STILL * area or (near_anchor and unsettled > UNSETTLED * area):
            continue
        near = _near(labels, i, y0, y1, x0, x1, ring)
        sums = np.zeros((2, 2, 3))  # inside / around, frame / model, channel
        around = 0
        for v in range(y0, y1):
            for u in range(x0, x1):
                if labels[v, u] == i:
                    side = 0
                elif near[v - y0, u - x0] and fg[v, u] == 0:
                    side = 1
                    around += 1
                else:
                    continue
                for c in range(3):
                    sums[side, 0, c] += ycc[v, u, c]
                    sums[side, 1, c] += mean[v, u, c]
        if around < ring:
            continue
        seen = learned = 0.0
        for c in range(3):
            d = sums[0, 0, c] / area - sums[1, 0, c] / around
            seen += d * d
            d = sums[0, 1, c] / area - sums[1, 1, c] / around
            learned += d * d
        seen, learned = np.sqrt(seen), np.sqrt(learned)
        if learned >= 2 * match and seen <= max(match, learned / 4):
            found += 1
            for v in range(top, top + h):
                for u in range(left, left + w):
                    if labels[v, u] == i:
                        out[v, u] = True
    return out, found


@jit
def _any(mask: np.ndarray, y0: int, y1: int, x0: int, x1: int) -> bool:
    """Whether ``mask`` holds anywhere in rows ``y0:y1``, columns ``x0:x1``."""
    for v in range(y0, y1):
        for u in range(x0, x1):
            if mask[v, u]:
                return True
    return False


@jit
def _near(labels: np.ndarray, i: int, y0: int, y1: int, x0: int, x1: int, ring: int) -> np.ndarray:
    """Bool of the box ``y0:y1, x0:x1``: within ``ring`` pixels (a square) of label ``i``
    (a dilation, in rows then columns)."""
    h, w = y1 - y0, x1 - x0
    rows = np.zeros((h, w), np.bool_)
    for v in range(h):
        for u in range(w):
            if labels[y0 + v, x0 + u] == i:
                for k in range(max(u - ring, 0), min(u + ring + 1, w)):
                    rows[v, k] = True
    out = np.zeros((h, w), np.bool_)
    for v in range(h):
        for u in range(w):
            if rows[v, u]:
                for k in range(max(v - ring, 0), min(v + ring + 1, h)):
                    out[k, u] = True
    return out
