"""Ghosts in the moving head's background: the per-pixel model's ghost test over the map.

Someone who stood in view while the head swept during calibration is learned into the
directions they covered; once they walk off, the floor there is foreground from every view, and
an anchor lives on it. The test is the per-pixel model's
(:func:`percept.perception.light.maintenance.ghost_mask`, with its criteria and hold), asked of
the map brought into the frame's view: a still region whose frame matches the frame around it
while the map inside does not match the map around it. Its directions are forgotten
(:meth:`~percept.perception.view.mosaic.ViewMosaic.forget`): never foreground while unknown,
so the anchor on them loses its support, and learned anew from the frames once quiet
(:meth:`~percept.perception.view.mosaic.ViewMosaic.learn`).

How long a region has been foreground is kept per direction, not per pixel: the head turns.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from percept.perception.light.maintenance import GHOST_EVERY, GHOST_HOLD, box_mask, ghost_mask
from percept.perception.tracking.motion import Motion
from percept.perception.view.follow import FrameView
from percept.perception.view.ghosts_kernels import map_in_view
from percept.perception.view.learning_kernels import mark_cells
from percept.perception.view.mosaic import ViewMosaic


class ViewGhosts:
    """When each direction of ``mosaic`` was last background, and the ghost test every
    :data:`~percept.perception.light.maintenance.GHOST_EVERY` seconds. ``match`` (grey levels)
    and ``min_pixels`` (grid pixels) are the per-pixel test's; ``step`` the grid the frames
    come on (the anchors' boxes are in image pixels)."""

    def __init__(self, mosaic: ViewMosaic, match: float, min_pixels: int, step: int) -> None:
        self.mosaic = mosaic
        self.match, self.min_pixels, self.step = match, min_pixels, step
        self.background_at = np.zeros(mosaic.directions.rows * mosaic.directions.cols)
        """Time each direction was last seen as background (0: the start, as per pixel)."""
        self.tested_at = -math.inf
        self.found = 0
        """Ghost regions found."""

    def mark(self, view: FrameView, fg: np.ndarray, t: float) -> None:
        """The directions of ``view`` that ``fg`` (0/1 (H, W)) shows as background at ``t``."""
        mark_cells(self.background_at, view.nearest, fg, float(t))

    def test(
        self,
        view: FrameView,
        ycc: np.ndarray,
        fg: np.ndarray,
        moved: Motion,
        boxes: np.ndarray,
        t: float,
    ) -> int:
        """Forget the directions of the ghosts among the foreground ``fg`` of frame ``ycc``
        seen in ``view``, with the anchors' ``boxes`` (n, 4, image pixels), when a test is
        due; returns how many directions were forgotten."""
        if t - self.tested_at < GHOST_EVERY or not fg.any():
            return 0
        self.tested_at = t
        nearest, known = view.nearest, view.known
        learned = self.mosaic.mean.reshape(-1, 3)
        mean, settled = map_in_view(
            ycc, nearest, known, learned, self.background_at, t - GHOST_HOLD
        )
        # The test reads the previous frame at the foreground's pixels only.
        previous, moving, _ = moved.per_pixel(fg == 0)
        ghosts = ghost_mask(
            fg,
            ycc,
            mean,
            box_mask(boxes, fg.shape, self.step),
            settled,
            previous,
            moving,
            self.min_pixels,
            self.match,
        )
        # The bounds of a direction take in its neighbours' (``spread``): the region's edge,
        # learned in as well, is background already; forgotten with it, it is learned anew.
        size = 2 * (self.mosaic.view.spread + 1) + 1
        ghosts = cv2.dilate(ghosts.view(np.uint8), np.ones((size, size), np.uint8)) > 0
        cells = np.unique(nearest[ghosts & known]).astype(np.intp)
        if len(cells) == 0:
            return 0
        self.mosaic.forget(cells)
        self.found += 1
        return len(cells)
