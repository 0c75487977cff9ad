"""Merging groups of percepts into one percept each."""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def merge_groups(
    groups: np.ndarray,
    n_groups: int,
    boxes: np.ndarray,
    histograms: np.ndarray,
    counts: np.ndarray,
    regions: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(boxes, histograms, counts, regions)`` of groups ``0..n_groups-1`` of percepts.

    A group's box is the union of its percepts' boxes (left, top, width, height), its histograms
    the pixel-count weighted mean of theirs, its count their sum and its region its first
    percept's (-1 for a group without percepts).
    """
    left = np.full(n_groups, np.inf)
    top = np.full(n_groups, np.inf)
    right = np.full(n_groups, -np.inf)
    bottom = np.full(n_groups, -np.inf)
    total = np.zeros(n_groups)
    hist = np.zeros((n_groups, histograms.shape[1], histograms.shape[2]))
    first = np.full(n_groups, -1, np.intp)
    for i in range(len(groups)):
        g = groups[i]
        left[g] = min(left[g], boxes[i, 0])
        top[g] = min(top[g], boxes[i, 1])
        right[g] = max(right[g], boxes[i, 0] + boxes[i, 2])
        bottom[g] = max(bottom[g], boxes[i, 1] + boxes[i, 3])
        total[g] += counts[i]
        hist[g] += histograms[i] * counts[i]
        if first[g] < 0:
            first[g] = regions[i]
    out_boxes = np.empty((n_groups, 4))
    for g in range(n_groups):
        hist[g] /= total[g]
        out_boxes[g, 0], out_boxes[g, 1] = left[g], top[g]
        out_boxes[g, 2], out_boxes[g, 3] = right[g] - left[g], bottom[g] - top[g]
    return out_boxes, hist, total.astype(np.intp), first
