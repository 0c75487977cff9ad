"""Keeping the model's mean right: selective maintenance, ghosts, re-learning.

The mean of a pixel follows the (compensated) frame only where nothing is going on: the pixel
has been background and still for ``quiet`` seconds and lies in no anchor's box. It follows with
time constant ``maintain_time``, in steps every ``maintain_every`` seconds. A placed object is
foreground from the first frame on, so it never becomes quiet and is never learned in, however
long it stays; the ``quiet`` delay keeps the edges of things that come and go out too.

A ghost is foreground only because the model is wrong there: someone stood there during the
calibration (or an object was taken away). Then the frame inside the region matches the frame
around it while the model inside does not match the model around it, the opposite of a placed
object. Ghost regions, and after a change the compensation cannot explain everything outside
the anchors, are re-learned at once from the frame. A region at an anchor is a ghost only after
it has been foreground for :data:`GHOST_HOLD` seconds: an anchor is born on a ghost while the
person who made it walks off (the place they leave is joined to their moving body, so it is not
still), and it would feed on the ghost for ever.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from percept.perception.light import masks_kernels as masks
from percept.perception.light.ghosts_kernels import ghost_regions
from percept.perception.light.maintenance_kernels import follow_quiet
from percept.perception.params import LightParams
from percept.perception.segmentation.background import BackgroundModel

RING = 3
"""Grid pixels around a region that count as its surroundings."""
GHOST_HOLD = 3.0
"""Seconds a region near an anchor must have been foreground to be tested as a ghost: a ghost
lasts, a body the colour of the floor passing over something learned in does not."""
GHOST_EVERY = 0.5
"""Seconds between ghost tests when all the foreground lies in the anchors' boxes."""


def refresh(model: BackgroundModel) -> None:
    """Recompute the foreground test's bounds after the mean changed."""
    model.lower, model.upper = model.bounds(model.params.k)


def relearn(model: BackgroundModel, ycc: np.ndarray, where: np.ndarray) -> None:
    """The frame ``ycc`` becomes the mean where ``where`` (bool (H, W)) holds."""
    model.mean[where] = ycc[where]
    refresh(model)


def changed(ycc: np.ndarray, previous: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """Bool (H, W): the pixels of ``ycc`` that differ from ``previous`` by more than ``bound``
    (uint8 (H, W, 3), grey levels) in any channel: the motion test before noise reduction."""
    return np.any(cv2.absdiff(ycc, previous) > bound, axis=2)


def box_mask(boxes: np.ndarray, shape: tuple[int, int], step: int) -> np.ndarray:
    """Bool (H, W) of a grid of ``step``: True inside any of the boxes (left, top, width,
    height in image pixels; compiled: :func:`percept.perception.light.masks_kernels.box_mask`)."""
    return masks.box_mask(boxes, shape[0], shape[1], step)


def ghost_mask(
    fg: np.ndarray,
    ycc: np.ndarray,
    mean: np.ndarray,
    anchored: np.ndarray,
    settled: np.ndarray,
    previous: np.ndarray | None,
    moving: np.ndarray,
    min_pixels: int,
    match: float,
) -> np.ndarray:
    """Bool (H, W): the regions of the 0/1 foreground ``fg`` of at least ``min_pixels`` and still
    that are ghosts (see the module docstring) against the model's ``mean`` (float (H, W, 3):
    the per-pixel model's, or the moving head's map brought into the frame's view); one near
    the ``anchored`` pixels is tested from a few pixels on once it is ``settled`` (foreground
    for :data:`GHOST_HOLD` s). A region is
    still when at most 1 % of its pixels differ from the ``previous`` frame (None: the first
    frame) by more than ``moving`` (uint8 (H, W, 3), grey levels): a passing car is not still,
    an empty spot is.
    ``match`` is in grey levels (distance of mean colours): the model inside must be at least
    twice that far from the model around, the frame inside within it of the frame around (or
    within a quarter of the model's distance, for a floor whose colour varies). The labelling and
    the test of each region are compiled
    (:func:`percept.perception.light.ghosts_kernels.ghost_regions`)."""
    ghosts, _ = ghost_regions(
        np.ascontiguousarray(fg),
        ycc,
        mean,
        anchored,
        settled,
        ycc if previous is None else previous,
        moving,
        min_pixels,
        float(match),
        RING,
    )
    return ghosts


class Maintenance:
    """When each pixel was last busy, and the slow update of the quiet ones."""

    def __init__(self, shape: tuple[int, int], params: LightParams) -> None:
        self.params = params
        self.busy = np.full(shape, -np.inf)
        """Time each pixel was last foreground or moving."""
        self._last: float | None = None

    def mark(self, where: np.ndarray, t: float) -> None:
        """Pixels ``where`` (0/1 uint8 (H, W)) are busy at time ``t``."""
        masks.mark(self.busy, where, float(t), True)

    def due(self, t: float) -> bool:
        """Whether a maintenance step is due at time ``t`` (the first call starts the clock)."""
        if self._last is None:
            self._last = t
        return t - self._last >= self.params.maintain_every

    def step(self, model: BackgroundModel, ycc: np.ndarray, anchored: np.ndarray, t: float) -> int:
        """Quiet pixels outside ``anchored`` follow ``ycc`` for the time since the last step;
        returns how many were updated (compiled:
        :func:`percept.perception.light.maintenance_kernels.follow_quiet`)."""
        p = self.params
        elapsed = t - (self._last if self._last is not None else t)
        self._last = t
        if elapsed <= 0:
            return 0
        rate = np.float32(1.0 - math.exp(-elapsed / p.maintain_time))
        return follow_quiet(
            model.mean,
            model.sigma,
            model.lower,
            model.upper,
            ycc,
            self.busy,
            anchored,
            float(t),
            p.quiet,
            rate,
            model.params.k,
            model.params.sigma_min,
        )
