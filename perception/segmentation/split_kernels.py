"""The colour split's kernels: classifying the foreground pixels with the models' colours, and
cutting the regions that hold several classes into connected pieces.

The pieces of one (region, class) pair are labelled by union-find over the pair's pixels in
raster order, 8-connected, inside the region's box. They come out in the order OpenCV's Grana
labelling numbers them when every pair is laid out as a tile of one strip image, the tiles one
pixel apart (the layout the split used before it was compiled): Grana numbers components in the
order of their first 2x2 block in a raster scan of the blocks.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.segmentation.labelling.forest_kernels import find, union


@jit
def classify(
    boxes: np.ndarray,
    offsets: np.ndarray,
    pixel_bins: np.ndarray,
    model_boxes: np.ndarray,
    models: np.ndarray,
    threshold: float,
    margin: float,
) -> np.ndarray:
    """Class of every region pixel: 0 for no model, ``j + 1`` for model ``j``.

    Only the models whose box (left, top, width, height), grown by ``margin`` times its size on
    each side, overlaps a region's box compete for its pixels; a pixel goes to the one of largest
    ``p_j``, the product over the factors of model ``j``'s histogram at the pixel's bin
    (``M_j^Y(b_Y) M_j^Cr(b_Cr) M_j^Cb(b_Cb)`` for the marginals; the first of equals), or to no
    model when that is below ``threshold``.
    """
    n_models = len(model_boxes)
    factors = models.shape[1]
    classes = np.zeros(offsets[-1], np.intp)
    near = np.empty(n_models, np.intp)
    for r in range(len(boxes)):
        k = 0
        for j in range(n_models):
            x, y, w, h = model_boxes[j, 0], model_boxes[j, 1], model_boxes[j, 2], model_boxes[j, 3]
            grow_x, grow_y = w * margin, h * margin
            if (
                boxes[r, 0] < x + w + grow_x
                and x - grow_x < boxes[r, 0] + boxes[r, 2]
                and boxes[r, 1] < y + h + grow_y
                and y - grow_y < boxes[r, 1] + boxes[r, 3]
            ):
                near[k] = j
                k += 1
        if k == 0:
            continue
        for i in range(offsets[r], offsets[r + 1]):
            b0, b1 = pixel_bins[i, 0], pixel_bins[i, 1]
            b2 = pixel_bins[i, 2] if factors == 3 else 0
            best, top = -1, -1.0
            for q in range(k):
                j = near[q]
                p = models[j, 0, b0] * models[j, 1, b1]
                if factors == 3:
                    p *= models[j, 2, b2]
                if p > top:
                    best, top = j, p
            if top >= threshold:
                classes[i] = best + 1
    return classes


@jit
def split(
    boxes: np.ndarray,
    counts: np.ndarray,
    histograms: np.ndarray,
    offsets: np.ndarray,
    pixels: np.ndarray,
    pixel_bins: np.ndarray,
    classes: np.ndarray,
    n_classes: int,
    width: int,
    min_pixels: int,
    step: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Percepts from classified region pixels: ``(boxes, histograms, counts, regions)``.

    A region with at least two classes of ``min_pixels`` (grid) pixels or more is cut into the
    connected pieces of each such class (of ``min_pixels`` or more); the other regions, and those
    left without pieces, are one percept each, first, in region order; the pieces follow. Boxes
    and counts of regions are in image pixels; ``width`` is the grid's, ``step`` its spacing.
    """
    n = len(boxes)
    factors, m = histograms.shape[1], histograms.shape[2]
    class_count = np.zeros((n, n_classes), np.intp)
    for r in range(n):
        for i in range(offsets[r], offsets[r + 1]):
            class_count[r, classes[i]] += 1

    # Pairs (region, class) to cut, in order, and the strip tile each would have.
    pair_region = np.empty(n * n_classes, np.intp)
    pair_class = np.empty(n * n_classes, np.intp)
    pair_x = np.empty(n * n_classes, np.intp)
    n_pairs, members, strip_x, largest = 0, 0, 0, 0
    for r in range(n):
        significant = 0
        for c in range(n_classes):
            if class_count[r, c] >= min_pixels:
                significant += 1
        if significant < 2:
            continue
        w, h = boxes[r, 2] // step, boxes[r, 3] // step
        largest = max(largest, w * h)
        for c in range(n_classes):
            if class_count[r, c] >= min_pixels:
                pair_region[n_pairs], pair_class[n_pairs], pair_x[n_pairs] = r, c, strip_x
                strip_x += w + 1
                members += class_count[r, c]
                n_pairs += 1

    # Label each pair's pixels; piece statistics, and each member pixel's piece.
    local = np.zeros(largest, np.intp)  # provisional label + 1 of each pixel of the box
    parent = np.empty(members, np.intp)
    root_piece = np.empty(members, np.intp)
    member = np.empty(members, np.intp)  # index into the region pixels
    member_label = np.empty(members, np.intp)
    member_piece = np.empty(members, np.intp)
    area = np.zeros(members, np.intp)
    x0 = np.empty(members, np.intp)
    x1 = np.empty(members, np.intp)
    y0 = np.empty(members, np.intp)
    y1 = np.empty(members, np.intp)
    first_block = np.empty(members, np.intp)
    piece_region = np.empty(members, np.intp)
    block_row = strip_x  # wider than the strip: row-major keys of the 2x2 blocks
    n_pieces, done, n_labels = 0, 0, 0
    for q in range(n_pairs):
        r, c = pair_region[q], pair_class[q]
        bx, by, bw = boxes[r, 0] // step, boxes[r, 1] // step, boxes[r, 2] // step
        start, first_label = done, n_labels
        for i in range(offsets[r], offsets[r + 1]):
            if classes[i] != c:
                continue
            y = pixels[i] // width
            lx, ly = pixels[i] - y * width - bx, y - by
            label = -1
            for dx, dy in ((-1, 0), (-1, -1), (0, -1), (1, -1)):
                nx, ny = lx + dx, ly + dy
                if nx < 0 or nx >= bw or ny < 0:
                    continue
                other = local[ny * bw + nx] - 1
                if other < 0:
                    continue
                if label >= 0:
                    union(parent, label, other)
                label = find(parent, other)
            if label < 0:
                label = n_labels
                parent[label] = label
                n_labels += 1
            local[ly * bw + lx] = label + 1
            member[done], member_label[done] = i, label
            done += 1
        for label in range(first_label, n_labels):
            if find(parent, label) == label:
                root_piece[label] = n_pieces
                piece_region[n_pieces] = r
                area[n_pieces] = 0
                n_pieces += 1
        for k in range(start, done):
            i = member[k]
            piece = root_piece[find(parent, member_label[k])]
            member_piece[k] = piece
            y = pixels[i] // width
            x = pixels[i] - y * width
            key = ((y - by) // 2) * block_row + (x - bx + pair_x[q]) // 2
            if area[piece] == 0:
                x0[piece], x1[piece], y0[piece], y1[piece] = x, x, y, y
                first_block[piece] = key
            area[piece] += 1
            x0[piece], x1[piece] = min(x0[piece], x), max(x1[piece], x)
            y1[piece] = y  # raster order: the first pixel is on the top row, the last at the bottom
            first_block[piece] = min(first_block[piece], key)
            local[(y - by) * bw + (x - bx)] = 0  # clean for the next pair

    # The pieces kept, in Grana's order; regions with at least one are cut.
    kept = np.empty(n_pieces, np.intp)
    n_kept = 0
    for piece in range(n_pieces):
        if area[piece] >= min_pixels:
            kept[n_kept] = piece
            n_kept += 1
    kept = kept[:n_kept]
    kept = kept[np.argsort(first_block[kept])]
    rank = np.full(n_pieces, -1, np.intp)
    cut = np.zeros(n, np.bool_)
    for j in range(n_kept):
        rank[kept[j]] = j
        cut[piece_region[kept[j]]] = True
    n_whole = n - cut.sum()

    out_boxes = np.empty((n_whole + n_kept, 4))
    out_hist = np.zeros((n_whole + n_kept, factors, m))
    out_counts = np.empty(n_whole + n_kept, np.intp)
    out_regions = np.empty(n_whole + n_kept, np.intp)
    row = 0
    for r in range(n):
        if cut[r]:
            continue
        out_boxes[row] = boxes[r]
        out_hist[row] = histograms[r]
        out_counts[row], out_regions[row] = counts[r], r
        row += 1
    for j in range(n_kept):
        piece = kept[j]
        out_boxes[row + j, 0] = x0[piece] * step
        out_boxes[row + j, 1] = y0[piece] * step
        out_boxes[row + j, 2] = (x1[piece] - x0[piece] + 1) * step
        out_boxes[row + j, 3] = (y1[piece] - y0[piece] + 1) * step
        out_counts[row + j] = area[piece] * step * step
        out_regions[row + j] = piece_region[piece]
    for k in range(members):
        j = rank[member_piece[k]]
        if j < 0:
            continue
        for f in range(factors):
            out_hist[row + j, f, pixel_bins[member[k], f]] += 1.0
    for j in range(n_kept):
        out_hist[row + j] /= area[kept[j]]
    return out_boxes, out_hist, out_counts, out_regions
