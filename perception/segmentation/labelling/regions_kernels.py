"""Connected foreground regions from a 0/1 mask, with their boxes, counts, pixels and
histograms, in two passes over the mask's foreground.

The first pass labels the pixels in raster order (8-connected, union-find) and collects each
provisional label's pixel count, box and first 2x2 block; the components are then numbered as
OpenCV's Grana labelling numbers them (the order of their first 2x2 block in a raster scan of the
blocks) and those with too few pixels dropped; the second pass writes the final labels and lays
the regions' pixels out region by region (in raster order inside a region) with their colour bins
and histograms. Both passes skip the background eight pixels at a time.
"""

from __future__ import annotations

import numpy as np

from percept.perception.colour_kernels import codes
from percept.perception.compiled import jit
from percept.perception.segmentation.labelling.forest_kernels import find, union


@jit
def label_regions(
    mask: np.ndarray,
    ycc: np.ndarray,
    min_pixels: int,
    shift: int,
    m: int,
    joint: bool,
    step: int,
) -> tuple[np.ndarray, ...]:
    """The 8-connected regions of the C-contiguous ``mask`` (non-zero: foreground) with at least
    ``min_pixels`` pixels, and the label image: ``(labels, label_ids, boxes, counts, offsets,
    pixels, pixel_region, pixel_bins, histograms)`` as
    :class:`percept.perception.segmentation.labelling.regions.Regions` holds them.

    ``labels`` (int32, 0: background) numbers every component as OpenCV's Grana labelling
    does: in the order of its first 2x2 block in a raster scan of the blocks. ``ycc`` is the
    YCrCb image of the same grid; a pixel's bins are its intensities ``>> shift``, of ``m`` bins
    per channel, Cr and Cb counted together with ``joint`` (:func:`.codes`: histograms (n, 3, m),
    or (n, 2, m * m)); boxes and counts are scaled from the grid to the image by ``step``.
    """
    height, width = mask.shape
    labels = np.zeros((height, width), np.int32)
    # Most of the image is background: eight pixels of the mask at once, as one 64-bit word.
    blocks = width // 8 if width % 8 == 0 else 0
    words = mask.reshape(-1)[: height * blocks * 8].view(np.uint64)
    # Provisional labels (+ 1 in ``labels``) by the usual decision tree over the neighbours
    # above and to the left, merged by union-find; each with its pixel count, box and the
    # raster key of its first 2x2 block. A label starts only after a background pixel, so
    # there are at most (width + 1) // 2 of them a row, and 4 in a word of the mask. (Arrays of
    # that size rather than grown: numba compiles a loop that may replace its arrays into one
    # several times slower.)
    most = height * ((width + 1) // 2)
    if blocks:
        most = 0
        for i in range(words.shape[0]):
            if words[i] != 0:
                most += 4
    parent = np.empty(most, np.intp)
    count = np.empty(most, np.intp)
    left = np.empty(most, np.intp)
    right = np.empty(most, np.intp)
    top = np.empty(most, np.intp)
    bottom = np.empty(most, np.intp)
    first = np.empty(most, np.intp)
    block_row = (width + 1) // 2
    n_provisional = 0
    for y in range(height):
        for x0 in range(0, width, 8):
            if blocks and words[y * blocks + x0 // 8] == 0:
                continue
            for x in range(x0, min(x0 + 8, width)):
                if mask[y, x] == 0:
                    continue
                north = labels[y - 1, x] - 1 if y > 0 else -1
                label = -1
                if north >= 0:
                    label = north  # the pixels left and above left touch it: one component
                else:
                    north_west = labels[y - 1, x - 1] - 1 if y > 0 and x > 0 else -1
                    north_east = labels[y - 1, x + 1] - 1 if y > 0 and x + 1 < width else -1
                    west = labels[y, x - 1] - 1 if x > 0 else -1
                    near = north_west if north_west >= 0 else west
                    if near >= 0:
                        label = near
                        if north_east >= 0:
                            union(parent, near, north_east)
                    elif north_east >= 0:
                        label = north_east
                if label < 0:
                    label = n_provisional
                    parent[label] = label
                    count[label] = 0
                    n_provisional += 1
                    left[label], right[label], top[label] = x, x, y
                    first[label] = (y // 2) * block_row + x // 2
                labels[y, x] = label + 1
                count[label] += 1
                left[label] = min(left[label], x)
                right[label] = max(right[label], x)
                bottom[label] = y
                first[label] = min(first[label], (y // 2) * block_row + x // 2)

    # Components: the roots, numbered in the order of their first block.
    for label in range(n_provisional):
        root = find(parent, label)
        if root != label:
            count[root] += count[label]
            left[root] = min(left[root], left[label])
            right[root] = max(right[root], right[label])
            top[root] = min(top[root], top[label])
            bottom[root] = max(bottom[root], bottom[label])
            first[root] = min(first[root], first[label])
    roots = np.empty(n_provisional, np.intp)
    n_components = 0
    for label in range(n_provisional):
        if parent[label] == label:
            roots[n_components] = label
            n_components += 1
    roots = roots[:n_components]
    roots = roots[np.argsort(first[roots])]
    final = np.empty(n_provisional, np.int32)  # label of each root
    region_of = np.full(n_provisional, -1, np.intp)  # region of each root
    n = 0
    for k in range(n_components):
        root = roots[k]
        final[root] = k + 1
        if count[root] >= min_pixels:
            region_of[root] = n
            n += 1
    label_ids = np.empty(n, np.int32)
    boxes = np.empty((n, 4), np.intp)
    counts = np.empty(n, np.intp)
    offsets = np.zeros(n + 1, np.intp)
    for k in range(n_components):
        root = roots[k]
        r = region_of[root]
        if r < 0:
            continue
        label_ids[r] = k + 1
        boxes[r, 0] = left[root] * step
        boxes[r, 1] = top[root] * step
        boxes[r, 2] = (right[root] - left[root] + 1) * step
        boxes[r, 3] = (bottom[root] - top[root] + 1) * step
        counts[r] = count[root] * step * step
        offsets[r + 1] = offsets[r] + count[root]
    for label in range(n_provisional):
        root = find(parent, label)
        final[label], region_of[label] = final[root], region_of[root]

    # The final labels, and the regions' pixels laid out region by region in raster order.
    total = offsets[n]
    pixels = np.empty(total, np.intp)
    pixel_region = np.empty(total, np.intp)
    factors, bins_each = (2, m * m) if joint else (3, m)
    pixel_bins = np.empty((total, factors), np.uint16)
    histograms = np.zeros((n, factors, bins_each))
    cursor = offsets[:n].copy()
    for y in range(height):
        for x0 in range(0, width, 8):
            if blocks and words[y * blocks + x0 // 8] == 0:
                continue
            for x in range(x0, min(x0 + 8, width)):
                label = labels[y, x] - 1
                if label < 0:
                    continue
                labels[y, x] = final[label]
                r = region_of[label]
                if r < 0:
                    continue
                k = cursor[r]
                cursor[r] += 1
                pixels[k] = y * width + x
                pixel_region[k] = r
                b0, b1, b2 = codes(ycc[y, x, 0], ycc[y, x, 1], ycc[y, x, 2], shift, m, joint)
                pixel_bins[k, 0], pixel_bins[k, 1] = b0, b1
                histograms[r, 0, b0] += 1.0
                histograms[r, 1, b1] += 1.0
                if not joint:
                    pixel_bins[k, 2] = b2
                    histograms[r, 2, b2] += 1.0
    for r in range(n):
        histograms[r] /= offsets[r + 1] - offsets[r]
    return labels, label_ids, boxes, counts, offsets, pixels, pixel_region, pixel_bins, histograms
