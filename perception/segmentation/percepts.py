"""Percepts (§4.2): the pieces of foreground that the anchors are fed with.

A percept is ``<x, y, w, h, M^Y, M^Cr, M^Cb, n>``: the centre and size of its bounding box in
pixels, its three normalised histograms and its pixel count, plus the foreground region it
came from. Inside the pipeline all percepts of a frame travel together as :class:`PerceptSet`
(arrays); :class:`Percept` is the one-at-a-time view handed to callers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from percept.perception.segmentation.percepts_kernels import merge_groups


@dataclass(frozen=True)
class Percept:
    """One percept: a connected piece of foreground of one colour class."""

    x: float
    """Centre of the bounding box, pixels from the left."""
    y: float
    """Centre of the bounding box, pixels from the top."""
    w: float
    """Width of the bounding box in pixels."""
    h: float
    """Height of the bounding box in pixels."""
    histograms: np.ndarray
    """(factors, bins) normalised colour model (:class:`~percept.perception.colour.Coding`):
    the Y, Cr and Cb histograms, or the Y and the joint CrCb histogram."""
    n: int
    """Pixels in the percept."""
    region: int
    """Index of the foreground region (in the frame's regions) it was cut from."""

    @property
    def bbox(self) -> tuple[float, float, float, float]:
        """(left, top, width, height) in pixels."""
        return (self.x - self.w / 2, self.y - self.h / 2, self.w, self.h)


@dataclass(frozen=True)
class PerceptSet:
    """All percepts of one frame as arrays, one row per percept."""

    boxes: np.ndarray
    """(k, 4) float: left, top, width, height."""
    histograms: np.ndarray
    """(k, factors, bins) normalised colour models."""
    counts: np.ndarray
    """(k,) pixel counts."""
    regions: np.ndarray
    """(k,) foreground region of each percept."""

    def __len__(self) -> int:
        return len(self.counts)

    def select(self, rows: np.ndarray) -> PerceptSet:
        """The percepts of ``rows`` (a boolean mask or indices)."""
        return PerceptSet(
            boxes=self.boxes[rows],
            histograms=self.histograms[rows],
            counts=self.counts[rows],
            regions=self.regions[rows],
        )

    @property
    def centres(self) -> np.ndarray:
        """(k, 2) centres of the boxes."""
        return self.boxes[:, :2] + self.boxes[:, 2:] / 2

    def to_list(self) -> list[Percept]:
        """One :class:`Percept` per row."""
        centres = self.centres
        return [
            Percept(
                x=float(c[0]),
                y=float(c[1]),
                w=float(b[2]),
                h=float(b[3]),
                histograms=hist,
                n=int(n),
                region=int(r),
            )
            for c, b, hist, n, r in zip(
                centres, self.boxes, self.histograms, self.counts, self.regions, strict=True
            )
        ]


def combine(groups: np.ndarray, n_groups: int, percepts: PerceptSet) -> PerceptSet:
    """Merge the percepts of each group 0..n_groups-1 into one (§4.4).

    The merged box is the union of the boxes (the box of the union of outlines); the merged
    histograms are the pixel-count weighted mean, which is the histogram of all their pixels.
    Every group must have at least one percept; ``regions`` keeps the first one's region.
    """
    boxes, histograms, counts, regions = merge_groups(
        groups, n_groups, percepts.boxes, percepts.histograms, percepts.counts, percepts.regions
    )
    return PerceptSet(boxes=boxes, histograms=histograms, counts=counts, regions=regions)


def empty(shape: tuple[int, int]) -> PerceptSet:
    """A set without percepts, with histograms of ``shape`` (factors, bins)."""
    return PerceptSet(
        boxes=np.zeros((0, 4)),
        histograms=np.zeros((0, *shape)),
        counts=np.zeros(0, np.intp),
        regions=np.zeros(0, np.intp),
    )
