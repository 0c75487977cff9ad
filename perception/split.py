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


def overlapping(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) bool: which boxes ``(left, top, width, height)`` of a and b overlap."""
    ax0, ay0 = a[:, 0:1], a[:, 1:2]
    ax1, ay1 = ax0 + a[:, 2:3], ay0 + a[:, 3:4]
    bx0, by0 = b[:, 0], b[:, 1]
    bx1, by1 = bx0 + b[:, 2], by0 + b[:, 3]
    return (ax0 < bx1) & (bx0 < ax1) & (ay0 < by1) & (by0 < ay1)


def grow(boxes: np.ndarray, margin: float) -> np.ndarray:
    """Boxes grown by ``margin`` times their size on every side."""
    d = boxes[:, 2:] * margin
    return np.concatenate([boxes[:, :2] - d, boxes[:, 2:] + 2 * d], axis=1)


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
    m = model_histograms.shape[-1]
    candidates = overlapping(regions.boxes.astype(np.float64), grow(model_boxes, margin))
    n_candidates = candidates.sum(axis=1)
    table = likelihood_table(model_histograms)
    joint = joint_bins(regions.pixel_bins, m)
    owner = regions.pixel_region

    # One candidate: the pixel is that model's when p_j >= t; a single table lookup.
    single = (n_candidates == 1)[owner]
    j = np.argmax(candidates, axis=1)[owner[single]]
    accepted = (table >= threshold).ravel()[j * m**3 + joint[single]]
    classes[single] = np.where(accepted, j + 1, NO_MODEL)

    # Several candidates (objects that touch): argmax over them, region by region.
    for r in np.flatnonzero(n_candidates >= 2):
        px = np.flatnonzero(owner == r)
        models = np.flatnonzero(candidates[r])
        p = table[models][:, joint[px]]
        best = np.argmax(p, axis=0)
        ok = p[best, np.arange(len(px))] >= threshold
        classes[px] = np.where(ok, models[best] + 1, NO_MODEL)
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
    whole = regions_as_percepts(regions, np.flatnonzero(~mixed))
    pieces = [whole]
    for r in np.flatnonzero(mixed):
        pieces.append(_split_region(regions, classes, r, significant[r], width, min_pixels))
    return _concatenate(pieces)


def _split_region(
    regions: Regions,
    classes: np.ndarray,
    r: int,
    significant: np.ndarray,
    width: int,
    min_pixels: int,
) -> PerceptSet:
    """The connected pieces of each significant class inside region ``r``."""
    left, top, w, h = (int(v) for v in regions.boxes[r])
    px = np.flatnonzero(regions.pixel_region == r)
    flat = regions.pixels[px]
    xs, ys = flat % width - left, flat // width - top
    cls = classes[px]
    boxes, hists, counts = [], [], []
    for k in np.flatnonzero(significant):
        mine = cls == k
        image = np.zeros((h, w), np.uint8)
        image[ys[mine], xs[mine]] = 1
        n, labels, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(
            image, 8, cv2.CV_32S, cv2.CCL_GRANA
        )
        keep = np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= max(min_pixels, 1)) + 1
        if len(keep) == 0:
            continue
        piece = labels[ys[mine], xs[mine]]
        index = np.full(n, len(keep), np.intp)  # the extra group collects dropped specks
        index[keep] = np.arange(len(keep))
        m = regions.histograms.shape[-1]
        hist = grouped_histograms(index[piece], regions.pixel_bins[px[mine]], len(keep) + 1, m)
        boxes.append(stats[keep, :4] + (left, top, 0, 0))
        hists.append(hist[: len(keep)])
        counts.append(stats[keep, cv2.CC_STAT_AREA])
    if not boxes:
        return regions_as_percepts(regions, np.array([r]))
    total = np.concatenate(counts)
    return PerceptSet(
        boxes=np.concatenate(boxes).astype(np.float64),
        histograms=np.concatenate(hists),
        counts=total.astype(np.intp),
        regions=np.full(len(total), r, np.intp),
    )


def _concatenate(sets: list[PerceptSet]) -> PerceptSet:
    if len(sets) == 1:
        return sets[0]
    return PerceptSet(
        boxes=np.concatenate([s.boxes for s in sets]),
        histograms=np.concatenate([s.histograms for s in sets]),
        counts=np.concatenate([s.counts for s in sets]),
        regions=np.concatenate([s.regions for s in sets]),
    )
