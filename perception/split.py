"""Splitting foreground regions with the anchors' colour models (§4.2).

Every foreground pixel goes to the model ``j`` with the largest
``p_j(p) = M_j^Y(h(i_Y)) M_j^Cr(h(i_Cr)) M_j^Cb(h(i_Cb))``, or to "no model" when that is below
``t``; pixels of one class are then segmented again into connected pieces, the percepts.

Two choices keep this cheap and local. Only the models whose predicted box (grown by a margin)
overlaps a region compete for its pixels: a model on the other side of the image has nothing to
say about this region. And a region whose pixels all fall into one class (apart from fewer than
``min_pixels`` strays) is one percept as it is, with the histograms already computed for it; only
regions that really hold several classes are segmented again.
"""

from __future__ import annotations

import cv2
import numpy as np

from percept.perception.colour import grouped_histograms
from percept.perception.percepts import PerceptSet
from percept.perception.regions import Regions

NO_MODEL = 0
"""Pixel class of foreground that no model explains; model ``j`` is class ``j + 1``."""


def candidates(region_boxes: np.ndarray, model_boxes: np.ndarray, margin: float) -> np.ndarray:
    """(regions, models) bool: which model boxes, grown by ``margin`` times their size on each
    side, overlap which region boxes (all boxes left, top, width, height)."""
    grow = model_boxes[:, 2:] * margin
    m0 = model_boxes[:, :2] - grow
    m1 = model_boxes[:, :2] + model_boxes[:, 2:] + grow
    r0 = region_boxes[:, None, :2]
    r1 = r0 + region_boxes[:, None, 2:]
    return ((r0 < m1) & (m0 < r1)).all(axis=2)


def regions_as_percepts(regions: Regions, rows: np.ndarray | None = None) -> PerceptSet:
    """Each region (or each of ``rows``) as one percept, without splitting."""
    rows = np.arange(len(regions)) if rows is None else rows
    return PerceptSet(
        boxes=regions.boxes[rows].astype(np.float64),
        histograms=regions.histograms[rows],
        counts=regions.counts[rows].astype(np.intp),
        regions=rows.astype(np.intp),
    )


def likelihood(models: np.ndarray, j: np.ndarray | int, bins: np.ndarray) -> np.ndarray:
    """``p_j(p) = M_j^Y(h(i_Y)) M_j^Cr(h(i_Cr)) M_j^Cb(h(i_Cb))`` of pixels with ``bins``
    (``(p, 3)``) under models ``j`` (one per pixel, or one for all) of ``models`` ``(n, 3, m)``."""
    m = models.shape[-1]
    flat = models.reshape(-1)
    base = np.asarray(j) * (3 * m)
    return (
        flat[base + bins[:, 0]] * flat[base + (m + bins[:, 1])] * flat[base + (2 * m + bins[:, 2])]
    )


def classify_pixels(
    regions: Regions,
    model_boxes: np.ndarray,
    model_histograms: np.ndarray,
    threshold: float,
    margin: float,
) -> np.ndarray:
    """Class of every foreground pixel of ``regions``: :data:`NO_MODEL` or model index + 1."""
    classes = np.zeros(len(regions.pixels), np.intp)
    if len(model_boxes) == 0 or len(regions) == 0:
        return classes
    near = candidates(regions.boxes, model_boxes, margin)
    n_near = near.sum(axis=1)
    owner = regions.pixel_region

    # One candidate: the pixel is that model's when p_j >= t. (Evaluated for every pixel and
    # kept where the region has one candidate: cheaper than selecting those pixels first.)
    if (n_near == 1).any():
        j = np.argmax(near, axis=1)[owner]
        accepted = (likelihood(model_histograms, j, regions.pixel_bins) >= threshold) & (
            n_near == 1
        )[owner]
        classes = np.where(accepted, j + 1, NO_MODEL)

    # Several candidates (objects that touch): argmax over them, for all the regions with the
    # same candidates at once (one group per touching pair usually; one for all regions when
    # every model competes everywhere, as in the chapter).
    same: dict[bytes, list[int]] = {}
    for r in np.flatnonzero(n_near >= 2).tolist():
        same.setdefault(near[r].tobytes(), []).append(r)
    for rows in same.values():
        px = np.concatenate([np.arange(r.start, r.stop) for r in map(regions.members, rows)])
        bins = regions.pixel_bins[px]
        models = np.flatnonzero(near[rows[0]])
        best = np.full(len(px), models[0] + 1)
        top = likelihood(model_histograms, models[0], bins)
        for j in models[1:]:
            p = likelihood(model_histograms, j, bins)
            better = p > top
            best[better], top = j + 1, np.maximum(top, p)
        best[top < threshold] = NO_MODEL
        classes[px] = best
    return classes


def split_regions(
    regions: Regions, classes: np.ndarray, n_models: int, min_pixels: int
) -> PerceptSet:
    """Percepts from classified pixels: connected pieces (of at least ``min_pixels`` image
    pixels) of one class in each region."""
    min_pixels = regions.samples(min_pixels)
    n_classes = n_models + 1
    counts = np.bincount(
        regions.pixel_region * n_classes + classes, minlength=len(regions) * n_classes
    ).reshape(len(regions), n_classes)
    significant = counts >= min_pixels
    mixed = significant.sum(axis=1) >= 2
    if not mixed.any():
        return regions_as_percepts(regions)
    pieces = _pieces(regions, classes, significant & mixed[:, None], min_pixels)
    split = np.zeros(len(regions), bool)
    split[pieces.regions] = True  # a mixed region left without pieces stays whole
    whole = regions_as_percepts(regions, np.flatnonzero(~split))
    return PerceptSet(
        boxes=np.concatenate([whole.boxes, pieces.boxes]),
        histograms=np.concatenate([whole.histograms, pieces.histograms]),
        counts=np.concatenate([whole.counts, pieces.counts]),
        regions=np.concatenate([whole.regions, pieces.regions]),
    )


def _pieces(
    regions: Regions, classes: np.ndarray, chosen: np.ndarray, min_pixels: int
) -> PerceptSet:
    """The connected pieces (of at least ``min_pixels`` grid pixels) of the ``chosen`` (region,
    class) pairs.

    Every chosen pair gets a tile the size of its region's box in one strip image, the tiles a
    pixel apart, so that a single connected-components call labels the pieces of all pairs and
    no piece reaches from one tile into the next.
    """
    n_classes = chosen.shape[1]
    pairs = np.flatnonzero(chosen)  # region * n_classes + class
    tile_of = np.full(chosen.size, -1, np.intp)
    tile_of[pairs] = np.arange(len(pairs))
    tile = tile_of[regions.pixel_region * n_classes + classes]
    used = np.flatnonzero(tile >= 0)
    tile = tile[used]
    box = regions.boxes[pairs // n_classes] // regions.step  # each tile's region box, on the grid
    width = regions.labels.shape[1]
    tile_x = np.concatenate(([0], np.cumsum(box[:-1, 2] + 1)))
    strip_w, strip_h = int(tile_x[-1] + box[-1, 2]), int(box[:, 3].max())
    ys, xs = np.divmod(regions.pixels[used], width)
    local = (ys - box[tile, 1]) * strip_w + (xs - box[tile, 0] + tile_x[tile])
    strip = np.zeros(strip_h * strip_w, np.uint8)
    strip[local] = 1
    n, labels, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(
        strip.reshape(strip_h, strip_w), 8, cv2.CV_32S, cv2.CCL_GRANA
    )
    kept = np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= min_pixels) + 1
    index = np.full(n, len(kept), np.intp)  # the extra group collects dropped specks
    index[kept] = np.arange(len(kept))
    piece = index[np.take(labels.ravel(), local)]
    home = np.searchsorted(tile_x, stats[kept, cv2.CC_STAT_LEFT], side="right") - 1
    boxes = stats[kept, :4].astype(np.float64)
    boxes[:, 0] += box[home, 0] - tile_x[home]
    boxes[:, 1] += box[home, 1]
    m = regions.histograms.shape[-1]
    hist = grouped_histograms(piece, regions.pixel_bins[used], len(kept) + 1, m)
    step = regions.step
    return PerceptSet(
        boxes=boxes * step,
        histograms=hist[:-1],
        counts=stats[kept, cv2.CC_STAT_AREA].astype(np.intp) * step**2,
        regions=pairs[home] // n_classes,
    )
