"""Region boxes, counts, pixels and histograms from a label image, in two passes.

The first pass over the labels collects each label's pixel count and box and the flat index of
every labelled pixel in raster order; the second goes over those pixels only, dropping the
labels with too few pixels and laying the rest out region by region (in raster order inside a
region, as a stable sort by label would) with their colour bins and histograms.
"""

from __future__ import annotations

import numpy as np

from percept.perception.kernels import jit


@jit
def region_table(
    mask: np.ndarray,
    labels: np.ndarray,
    n_labels: int,
    ycc: np.ndarray,
    min_pixels: int,
    shift: int,
    m: int,
    step: int,
) -> tuple[np.ndarray, ...]:
    """The regions of ``labels`` (int32 labels 1..n_labels-1, 0: background), the labels of the
    C-contiguous 0/1 ``mask``, with at least ``min_pixels`` pixels.

    ``ycc`` is the YCrCb image of the same grid; a pixel's bin is its intensity ``>> shift``,
    of ``m`` bins. Returns ``(label_ids, boxes, counts, offsets, pixels, pixel_region,
    pixel_bins, histograms)`` as :class:`percept.perception.regions.Regions` holds them, boxes
    and counts scaled from the grid to the image by ``step``.
    """
    height, width = labels.shape
    count = np.zeros(n_labels, np.intp)
    left = np.full(n_labels, width, np.intp)
    right = np.zeros(n_labels, np.intp)
    top = np.full(n_labels, height, np.intp)
    bottom = np.zeros(n_labels, np.intp)
    # Each labelled pixel in raster order: its row, column and label.
    ys = np.empty(height * width, np.intp)
    xs = np.empty(height * width, np.intp)
    ls = np.empty(height * width, np.intp)
    # Most of the image is background: eight pixels of the mask at once, as one 64-bit word.
    blocks = width // 8 if width % 8 == 0 else 0
    words = mask.reshape(-1)[: height * blocks * 8].view(np.uint64)
    p = 0
    for y in range(height):
        for x0 in range(0, width, 8):
            if blocks and words[y * blocks + x0 // 8] == 0:
                continue
            for x in range(x0, min(x0 + 8, width)):
                label = labels[y, x]
                if label == 0:
                    continue
                ys[p], xs[p], ls[p] = y, x, label
                p += 1
                if count[label] == 0:
                    top[label] = y  # raster order: the first pixel is on the top row
                count[label] += 1
                bottom[label] = y
                left[label] = min(left[label], x)
                right[label] = max(right[label], x)

    region_of = np.full(n_labels, -1, np.intp)
    n = 0
    for label in range(1, n_labels):
        if count[label] >= min_pixels:
            region_of[label] = n
            n += 1
    label_ids = np.empty(n, np.int32)
    boxes = np.empty((n, 4), np.intp)
    counts = np.empty(n, np.intp)
    offsets = np.zeros(n + 1, np.intp)
    for label in range(1, n_labels):
        r = region_of[label]
        if r < 0:
            continue
        label_ids[r] = label
        boxes[r, 0] = left[label] * step
        boxes[r, 1] = top[label] * step
        boxes[r, 2] = (right[label] - left[label] + 1) * step
        boxes[r, 3] = (bottom[label] - top[label] + 1) * step
        counts[r] = count[label] * step * step
        offsets[r + 1] = offsets[r] + count[label]

    total = offsets[n]
    pixels = np.empty(total, np.intp)
    pixel_region = np.empty(total, np.intp)
    pixel_bins = np.empty((total, 3), np.uint8)
    histograms = np.zeros((n, 3, m))
    cursor = offsets[:n].copy()
    for i in range(p):
        r = region_of[ls[i]]
        if r < 0:
            continue
        y, x = ys[i], xs[i]
        k = cursor[r]
        cursor[r] += 1
        pixels[k] = y * width + x
        pixel_region[k] = r
        for c in range(3):
            b = ycc[y, x, c] >> shift
            pixel_bins[k, c] = b
            histograms[r, c, b] += 1.0
    for r in range(n):
        histograms[r] /= offsets[r + 1] - offsets[r]
    return label_ids, boxes, counts, offsets, pixels, pixel_region, pixel_bins, histograms
