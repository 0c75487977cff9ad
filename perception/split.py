"""Splitting foreground regions with the anchors' colour models (§4.2).

Every foreground pixel goes to the model ``j`` with the largest
``p_j(p) = M_j^Y(h(i_Y)) M_j^Cr(h(i_Cr)) M_j^Cb(h(i_Cb))``, or to "no model" when that is below
``t``; pixels of one class are then segmented again into connected pieces, the percepts.

Two choices keep this cheap and local. Only the models whose predicted box (grown by a margin)
overlaps a region compete for its pixels: a model on the other side of the image has nothing to
say about this region. And a region whose pixels all fall into one class (apart from fewer than
``min_pixels`` strays) is one percept as it is, with the histograms already computed for it; only
regions that really hold several classes are segmented again. With ``p_j`` tabulated over the
``m**3`` joint bins, classifying a pixel is one table lookup.
"""

from __future__ import annotations

import cv2
import numpy as np

from perception.colour import grouped_histograms, joint_bins, likelihood_table
from perception.percepts import PerceptSet
from perception.regions import Regions

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
    n_candidates = near.sum(axis=1)
    if not n_candidates.any():
        return classes
    m = model_histograms.shape[-1]
    table = likelihood_table(model_histograms)
    joint = joint_bins(regions.pixel_bins, m)
    owner = regions.pixel_region

    # One candidate: the pixel is that model's when p_j >= t; a single table lookup.
    single = (n_candidates == 1)[owner]
    j = np.argmax(near, axis=1)[owner[single]]
    accepted = (table >= threshold).ravel()[j * m**3 + joint[single]]
    classes[single] = np.where(accepted, j + 1, NO_MODEL)

    # Several candidates (objects that touch): the class of every joint bin by argmax over
    # them, then one lookup per pixel of the region.
    for r in np.flatnonzero(n_candidates >= 2):
        models = np.flatnonzero(near[r])
        by_bin, top = np.full(m**3, models[0] + 1), table[models[0]]
        for j in models[1:]:  # argmax over the few candidates, without a strided reduction
            better = table[j] > top
            by_bin[better], top = j + 1, np.maximum(top, table[j])
        by_bin[top < threshold] = NO_MODEL
        members = regions.members(r)
        classes[members] = by_bin[joint[members]]
    return classes


def split_regions(
    regions: Regions,
    classes: np.ndarray,
    n_models: int,
    width: int,
    min_pixels: int,
) -> PerceptSet:
    """Percepts from classified pixels: connected pieces of one class in each region."""
    n_classes = n_models + 1
    counts = np.bincount(
        regions.pixel_region * n_classes + classes, minlength=len(regions) * n_classes
    ).reshape(len(regions), n_classes)
    significant = counts >= max(min_pixels, 1)
    mixed = significant.sum(axis=1) >= 2
    if not mixed.any():
        return regions_as_percepts(regions)
    pieces = [regions_as_percepts(regions, np.flatnonzero(~mixed))]
    for r in np.flatnonzero(mixed):
        pieces.append(_split_region(regions, classes, r, significant[r], width, min_pixels))
    return PerceptSet(
        boxes=np.concatenate([s.boxes for s in pieces]),
        histograms=np.concatenate([s.histograms for s in pieces]),
        counts=np.concatenate([s.counts for s in pieces]),
        regions=np.concatenate([s.regions for s in pieces]),
    )


def _split_region(
    regions: Regions,
    classes: np.ndarray,
    r: int,
    significant: np.ndarray,
    width: int,
    min_pixels: int,
) -> PerceptSet:
    """The connected pieces (of at least ``min_pixels``) of each significant class in ``r``.

    Each class is labelled inside the box of its own pixels, so a region with many classes
    costs about its area once rather than once per class.
    """
    members = regions.members(r)
    cls = classes[members]
    order = np.argsort(cls, kind="stable")
    ends = np.cumsum(np.bincount(cls, minlength=len(significant)))
    ys, xs = np.divmod(regions.pixels[members][order], width)
    piece = np.full(len(cls), -1, np.intp)  # each sorted pixel's piece, -1 for dropped specks
    boxes: list[list[int]] = []
    counts: list[int] = []
    for k in np.flatnonzero(significant):
        part = slice(int(ends[k - 1]) if k else 0, int(ends[k]))
        y, x = ys[part], xs[part]
        left, top = int(x.min()), int(y.min())
        w, h = int(x.max()) - left + 1, int(y.max()) - top + 1
        local = (y - top) * w + (x - left)
        image = np.zeros(h * w, np.uint8)
        image[local] = 1
        _, labels, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(
            image.reshape(h, w), 8, cv2.CV_32S, cv2.CCL_GRANA
        )
        index = np.full(len(stats), -1, np.intp)
        for label, row in enumerate(stats.tolist()[1:], start=1):
            if row[4] >= max(min_pixels, 1):
                index[label] = len(counts)
                boxes.append([row[0] + left, row[1] + top, row[2], row[3]])
                counts.append(row[4])
        piece[part] = index[np.take(labels.ravel(), local)]
    if not counts:
        return regions_as_percepts(regions, np.array([r]))
    kept = piece >= 0
    m = regions.histograms.shape[-1]
    bins = regions.pixel_bins[members][order][kept]
    return PerceptSet(
        boxes=np.array(boxes, np.float64),
        histograms=grouped_histograms(piece[kept], bins, len(counts), m),
        counts=np.array(counts, np.intp),
        regions=np.full(len(counts), r, np.intp),
    )
