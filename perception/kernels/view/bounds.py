"""The moving head's background bounds brought into a frame's view, in one pass.

Every grid pixel takes the bounds of its nearest cell of the map (:mod:`percept.perception.view`):
the foreground test's lower and upper bound, the motion test's bound, the cell's brightness
(what the alignment compares the frame with; 0 where the cell is unknown) and its index (what
the learning adds the pixel to). The pixel's map
coordinates are interpolated here from those of the lattice of exact lookups
(:class:`~percept.perception.view.directions.Lattice`), with ``cv2.resize``'s weights and float32
arithmetic (the same coordinates to the bit), and never written out: at 640x480 on the bench's
mosaic a view cost 0.66 ms as a resize of the lattice to every pixel and a loop over those float
coordinates, 0.60 ms so (with the lattice's lookup, thread CPU time, alternating), and the
alignment no longer remaps the brightness on its own. Most of the loop's time is its nine byte
reads and writes per pixel. The nearest cell, not an interpolation: the bounds of every
cell already take in those of its neighbours (``ViewParams.spread`` >= 1 cell), so the half cell
by which the nearest one may lie off is inside them.
"""

from __future__ import annotations

import numpy as np

from percept.perception.kernels import jit


@jit
def bounds_in_view(
    coarse: np.ndarray,
    columns: np.ndarray,
    column_weights: np.ndarray,
    rows: np.ndarray,
    row_weights: np.ndarray,
    bounds: np.ndarray,
    brightness: np.ndarray,
    outside: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    moved: np.ndarray,
    model: np.ndarray,
    nearest: np.ndarray,
) -> None:
    """For each grid pixel, the cell of the map nearest to its map coordinates (column, row;
    rounded half to even, as ``np.rint`` and ``cv2.remap``'s nearest), which are those of the
    lattice ``coarse`` (lattice rows, cols, 2) float32 interpolated linearly: pixel (r, c) lies
    between lattice columns ``columns[c]`` with float32 weights ``column_weights[c]`` and rows
    ``rows[r]`` with ``row_weights[r]`` (along the rows first, as ``cv2.resize``). Into
    ``lower``, ``upper`` and ``moved`` (H, W, 3) uint8 the cell's ``bounds`` (map rows, cols, 9)
    uint8 (lower, upper, motion bound; three channels each), into ``model`` (H, W) uint8 its
    ``brightness`` (map rows, cols) uint8 (0: unknown), into ``nearest`` (H, W) int32 its flat
    index. A pixel whose nearest cell lies outside the map (or whose coordinates are NaN) takes
    ``outside`` (9,) uint8, brightness 0 and index -1."""
    map_rows, map_cols = brightness.shape
    height, width = nearest.shape
    # The lattice rows interpolated along x (the resize's first pass).
    across = np.empty((coarse.shape[0], width, 2), np.float32)
    for i in range(coarse.shape[0]):
        for c in range(width):
            x0, x1 = columns[c, 0], columns[c, 1]
            a0, a1 = column_weights[c, 0], column_weights[c, 1]
            for k in range(2):
                across[i, c, k] = coarse[i, x0, k] * a0 + coarse[i, x1, k] * a1
    # Flat arrays and rows taken out: the index arithmetic of more dimensions per byte costs
    # a fifth more.
    table, levels = bounds.reshape(-1), brightness.reshape(-1)
    low, high, bound = lower.reshape(-1), upper.reshape(-1), moved.reshape(-1)
    cell_of, level_of = nearest.reshape(-1), model.reshape(-1)
    for r in range(height):
        above, below = across[rows[r, 0]], across[rows[r, 1]]
        b0, b1 = row_weights[r, 0], row_weights[r, 1]
        for c in range(width):
            x = np.rint(above[c, 0] * b0 + below[c, 0] * b1)
            y = np.rint(above[c, 1] * b0 + below[c, 1] * b1)
            i = r * width + c
            p = 3 * i
            # Written so that NaN, which compares False, falls outside.
            if x >= 0 and x < map_cols and y >= 0 and y < map_rows:
                cell = int(y) * map_cols + int(x)
                level_of[i] = levels[cell]
                cell_of[i] = cell
                q = 9 * cell
                for k in range(3):
                    low[p + k] = table[q + k]
                    high[p + k] = table[q + 3 + k]
                    bound[p + k] = table[q + 6 + k]
            else:
                # (Not one branch that picks the row to copy: numba then copies four times
                # slower.)
                level_of[i] = 0
                cell_of[i] = -1
                for k in range(3):
                    low[p + k] = outside[k]
                    high[p + k] = outside[3 + k]
                    bound[p + k] = outside[6 + k]
