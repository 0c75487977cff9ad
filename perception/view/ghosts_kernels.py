"""The map brought into a frame's view for the ghost test of :mod:`percept.perception.view.ghosts`.

The test compares the map's mean colours inside a region with those around it, and tests a
region near an anchor only once its directions have been foreground long enough. Both per grid
pixel were numpy's gathers through the nearest cells (a boolean mask, the cells' indices under
it, a fancy index of the map, a scatter back), some 2 ms a test at 176x144 on a loaded machine;
one pass over the grid here.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def map_in_view(
    ycc: np.ndarray,
    nearest: np.ndarray,
    known: np.ndarray,
    learned: np.ndarray,
    background_at: np.ndarray,
    since: float,
) -> tuple[np.ndarray, np.ndarray]:
    """``(mean, settled)``: float32 (H, W, 3) the map's ``learned`` mean (cells, 3) float32 at
    the nearest cell (``nearest`` (H, W) int32, -1: outside the map) of each grid pixel whose
    cell is ``known`` (H, W) bool, the frame ``ycc`` (H, W, 3) uint8 elsewhere (where the map
    knows nothing, the frame stands for it); and bool (H, W) whether the pixel's cell was last
    background (``background_at``, flat per cell) at ``since`` or before (True outside the
    map)."""
    height, width = nearest.shape
    mean = np.empty((height, width, 3), np.float32)
    settled = np.empty((height, width), np.bool_)
    for v in range(height):
        for u in range(width):
            cell = nearest[v, u]
            if known[v, u]:
                for c in range(3):
                    mean[v, u, c] = learned[cell, c]
            else:
                for c in range(3):
                    mean[v, u, c] = ycc[v, u, c]
            settled[v, u] = cell < 0 or background_at[cell] <= since
    return mean, settled
