"""The moving head's background bounds brought into a frame's view, in one pass.

Every grid pixel takes the bounds of its nearest cell of the map (:mod:`percept.perception.view`):
the foreground test's lower and upper bound, the motion test's bound, and whether the cell is
known. Three bilinear ``cv2.remap`` calls of four-channel tables, one nearest of the brightness
and three copies down to three channels cost 0.8 ms a frame at 640x480; this loop reads each
cell's nine bytes once (0.4 ms). The nearest cell, not an interpolation: the bounds of every
cell already take in those of its neighbours (``ViewParams.spread`` >= 1 cell), so the half cell
by which the nearest one may lie off is inside them.
"""

from __future__ import annotations

import numpy as np

from percept.perception.kernels import jit


@jit
def bounds_in_view(
    cells: np.ndarray,
    bounds: np.ndarray,
    brightness: np.ndarray,
    outside: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    moved: np.ndarray,
    known: np.ndarray,
) -> None:
    """For each grid pixel, the cell of the map nearest to its map coordinates ``cells``
    (H, W, 2) float32 (column, row; rounded half to even, as ``np.rint`` and ``cv2.remap``'s
    nearest): its ``bounds`` (rows, cols, 9) uint8 (lower, upper, motion bound; three channels
    each) into ``lower``, ``upper`` and ``moved`` (H, W, 3) uint8, and whether its
    ``brightness`` (rows, cols) uint8 is above 0 into ``known`` (H, W) bool. A pixel whose
    nearest cell lies outside the map (or whose coordinates are NaN) takes ``outside`` (9,)
    uint8 and is not known."""
    rows, cols = brightness.shape
    height, width = known.shape
    for r in range(height):
        for c in range(width):
            x = np.rint(cells[r, c, 0])
            y = np.rint(cells[r, c, 1])
            # Written so that NaN, which compares False, falls outside.
            if x >= 0 and x < cols and y >= 0 and y < rows:
                iy, ix = int(y), int(x)
                known[r, c] = brightness[iy, ix] > 0
                for k in range(3):
                    lower[r, c, k] = bounds[iy, ix, k]
                    upper[r, c, k] = bounds[iy, ix, 3 + k]
                    moved[r, c, k] = bounds[iy, ix, 6 + k]
            else:
                # (Not one branch that picks the row to copy: numba then copies four times
                # slower.)
                known[r, c] = False
                for k in range(3):
                    lower[r, c, k] = outside[k]
                    upper[r, c, k] = outside[3 + k]
                    moved[r, c, k] = outside[6 + k]
