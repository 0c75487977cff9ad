"""Connected foreground regions (§4.1): box, pixel count, outline and colour histograms.

Regions are kept as arrays, one row per region, because every later step works on all of them
at once; the outline polygon is traced only when someone asks for it. Alongside the regions
this module keeps the foreground pixels themselves, grouped by region (flat index, region,
per-channel bins), which the colour split needs.

Labelling, boxes, counts, the pixels of each region and its histograms come from one compiled kernel
(:func:`.regions_kernels.label_regions`), which numbers the regions
as OpenCV's Grana labelling does and skips the background eight pixels at a time: most of a frame is
background, which OpenCV's labelling reads pixel by pixel (at 320x240 it cost more than the kernel's
work on the foreground).

Large images are worked on a grid: with ``step`` s > 1 the pipeline looks at every s-th pixel of
every s-th row only (:func:`subsample`), from the colour conversion on, which divides the work
of every later step by s^2. Boxes and counts are then given in image pixels (to within s - 1
pixels; counts as grid pixels times s^2); ``labels`` and ``pixels`` stay on the grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from percept.kinematics.camera import grid_shape
from percept.perception.colour import Coding
from percept.perception.segmentation.grid_kernels import every_step
from percept.perception.segmentation.labelling.regions_kernels import label_regions


@dataclass(frozen=True)
class Regions:
    """The foreground regions of one frame, and their pixels."""

    step: int
    """Only every ``step``-th pixel of every ``step``-th row was looked at (1: all)."""
    labels: np.ndarray
    """(H / step, W / step) int32 connected-component labels of the grid (0: background)."""
    label_ids: np.ndarray
    """(n,) label of each region in ``labels``."""
    boxes: np.ndarray
    """(n, 4) int: left, top, width, height in image pixels."""
    counts: np.ndarray
    """(n,) image pixels in each region."""
    offsets: np.ndarray
    """(n + 1,) region ``i``'s pixels are ``offsets[i]:offsets[i + 1]`` of ``pixels``."""
    histograms: np.ndarray
    """(n, factors, bins) normalised colour models (:class:`~percept.perception.colour.Coding`)
    of each region's pixels in the original image."""
    pixels: np.ndarray
    """(p,) flat grid index of each pixel of the regions, region by region, in raster order."""
    pixel_region: np.ndarray
    """(p,) region of each of those pixels."""
    pixel_bins: np.ndarray
    """(p, factors) uint16 bins of each of those pixels in each factor of the colour model."""

    def __len__(self) -> int:
        return len(self.boxes)

    def samples(self, pixels: int) -> int:
        """How many grid pixels stand for ``pixels`` image pixels (at least 1)."""
        return grid_samples(pixels, self.step)

    def members(self, i: int) -> slice:
        """Where region ``i``'s pixels are in ``pixels``, ``pixel_region`` and ``pixel_bins``."""
        return slice(int(self.offsets[i]), int(self.offsets[i + 1]))

    def outline(self, i: int) -> np.ndarray:
        """Outer polygon of region ``i`` as ``(k, 2)`` image points (x, y)."""
        left, top, w, h = (int(v) // self.step for v in self.boxes[i])
        crop = self.labels[top : top + h, left : left + w]
        inside = (crop == self.label_ids[i]).astype(np.uint8)
        contours, _ = cv2.findContours(inside, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        largest = max(contours, key=len)
        return (largest.reshape(-1, 2) + np.array([left, top])) * self.step


def grid_samples(pixels: int, step: int) -> int:
    """How many pixels of the grid of every ``step``-th pixel stand for ``pixels`` image pixels
    (at least 1)."""
    return max(1, math.ceil(pixels / step**2))


def grid_step(width: int, height: int, max_pixels: int) -> int:
    """The smallest step that leaves at most ``max_pixels`` grid pixels (1 when ``max_pixels``
    is 0: every pixel)."""
    if max_pixels <= 0:
        return 1
    step = 1
    while math.prod(grid_shape(width, height, step)) > max_pixels:
        step += 1
    return step


def subsample(image: np.ndarray, step: int) -> np.ndarray:
    """``image[::step, ::step]`` (H, W) or (H, W, C) uint8, as a contiguous array (compiled:
    :func:`percept.perception.segmentation.grid_kernels.every_step`)."""
    if step == 1:
        return image
    height, width = image.shape[:2]
    rows = np.ascontiguousarray(image).reshape(height, -1)
    grid = every_step(rows, step, rows.shape[1] // width)
    return grid.reshape((grid.shape[0], -1, *image.shape[2:]))


def find_regions(
    mask: np.ndarray, ycc: np.ndarray, coding: Coding, min_pixels: int, step: int = 1
) -> Regions:
    """Regions of the 0/1 ``mask`` with at least ``min_pixels`` (image) pixels; histograms of
    ``coding`` from ``ycc``. ``mask`` and ``ycc`` are the grid of every ``step``-th pixel."""
    table = label_regions(
        np.ascontiguousarray(mask),
        ycc,
        grid_samples(min_pixels, step),
        coding.shift,
        coding.m,
        coding.joint,
        step,
    )
    return regions_of(table, step)


def regions_of(table: tuple[np.ndarray, ...], step: int) -> Regions:
    """The :class:`Regions` of the nine arrays that
    :func:`~.regions_kernels.label_regions` gives, on the grid of
    every ``step``-th pixel."""
    labels, label_ids, boxes, counts, offsets, pixels, pixel_region, pixel_bins, histograms = table
    return Regions(
        step=step,
        labels=labels,
        label_ids=label_ids,
        boxes=boxes,
        counts=counts,
        offsets=offsets,
        histograms=histograms,
        pixels=pixels,
        pixel_region=pixel_region,
        pixel_bins=pixel_bins,
    )
