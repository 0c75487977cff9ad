"""Where tracking errors come from: every box that the frame's pairing leaves alone, by what is
near it.

In each frame, true objects (clipped to the image) and anchor boxes are paired one to one at
IoU 0.5 or more (:func:`~percept.perception.evaluation.tracking.iou_pairs`); anchor boxes on an
ignored object go first. What is left is classified by its nearest partner at IoU above 0.1 (an
unpaired one first, else any):

- an object with no box near it is a *miss*; an anchor box with no object near it a *false box*;
- an object whose nearest box is bigger is *merged* (into a neighbour or a shadow) and that box
  is *too big*;
- an anchor box smaller than its nearest object lies *on a part* of it, and an object whose
  nearest box is smaller is *cut*.

Counts are of boxes summed over frames; their shares are of the true boxes, as MOTA's errors.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from percept.perception.evaluation.tracking import clip_boxes, iou, iou_pairs, split_gt

NEAR = 0.1
"""IoU above which an unpaired box has a partner and is of the wrong extent, not alone."""


@dataclass(frozen=True)
class ErrorClasses:
    """Counts of true and anchor boxes, summed over the frames of a sequence (or of many)."""

    boxes: int
    """True boxes scored."""
    matched: int
    misses: int
    false_boxes: int
    merged: int
    too_big: int
    on_a_part: int
    cut: int

    def __add__(self, other: ErrorClasses) -> ErrorClasses:
        return ErrorClasses(*(getattr(self, f.name) + getattr(other, f.name) for f in fields(self)))

    def shares(self) -> dict[str, float]:
        """Each class over the true boxes (0 for none), rounded to 4 places."""
        return {
            f.name: round(getattr(self, f.name) / self.boxes, 4) if self.boxes else 0.0
            for f in fields(self)
            if f.name != "boxes"
        }

    @staticmethod
    def from_counts(counts: Mapping[str, int]) -> ErrorClasses:
        return ErrorClasses(**{f.name: int(counts[f.name]) for f in fields(ErrorClasses)})


NONE = ErrorClasses(0, 0, 0, 0, 0, 0, 0, 0)


def _frame(g: np.ndarray, h: np.ndarray) -> ErrorClasses:
    """One frame's classes; ``g`` and ``h`` are (left, top, width, height) boxes."""
    if not len(g) or not len(h):
        return ErrorClasses(len(g), 0, len(g), len(h), 0, 0, 0, 0)
    s = iou(g, h)
    pairs = iou_pairs(s, 0.5)
    free_g = sorted(set(range(len(g))) - {r for r, _ in pairs})
    free_h = sorted(set(range(len(h))) - {c for _, c in pairs})
    area_g, area_h = g[:, 2] * g[:, 3], h[:, 2] * h[:, 3]
    misses = merged = cut = 0
    for r in free_g:
        near = [c for c in free_h if s[r, c] > NEAR] or [c for c in range(len(h)) if s[r, c] > NEAR]
        if not near:
            misses += 1
        elif area_h[max(near, key=lambda c: s[r, c])] > area_g[r]:
            merged += 1
        else:
            cut += 1
    false = too_big = part = 0
    for c in free_h:
        near = [r for r in range(len(g)) if s[r, c] > NEAR]
        if not near:
            false += 1
        elif area_h[c] > area_g[max(near, key=lambda r: s[r, c])]:
            too_big += 1
        else:
            part += 1
    return ErrorClasses(len(g), len(pairs), misses, false, merged, too_big, part, cut)


def error_classes(
    gt: np.ndarray, hypotheses: np.ndarray, image_size: tuple[int, int] | None = None
) -> ErrorClasses:
    """The error classes of anchor boxes against the truth (MOT rows), true boxes clipped to
    ``image_size`` (width, height) when given."""
    scored, ignored = split_gt(gt)
    total = NONE
    frames = set(scored[:, 0].astype(int)) | set(hypotheses[:, 0].astype(int))
    for f in sorted(frames):
        g = clip_boxes(scored[scored[:, 0] == f][:, 2:6], image_size)
        h = hypotheses[hypotheses[:, 0] == f][:, 2:6]
        ign = ignored[ignored[:, 0] == f][:, 2:6]
        if len(ign) and len(h):
            h = h[iou(h, ign).max(axis=1) < 0.5]
        total = total + _frame(g, h)
    return total
