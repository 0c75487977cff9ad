"""The moving head's background bounds brought into a frame's view, in one pass.

Every grid pixel takes the bounds of its nearest cell of the map (:mod:`percept.perception.view`):
the foreground test's lower and upper bound, the motion test's bound, the cell's brightness
(what the alignment compares the frame with; 0 where the cell is unknown) and its index (what
the learning adds the pixel to). The pixel's map coordinates are interpolated here from those of
the lattice of exact lookups (:class:`~percept.perception.view.map.directions.Lattice`), with
``cv2.resize``'s weights and float32 arithmetic (the same coordinates to the bit), and never
written out. The nearest cell, not an interpolation: the bounds of every cell already take in
those of its neighbours (``ViewParams.spread`` >= 1 cell), so the half cell by which the nearest
one may lie off is inside them.

Most of the time is moving bytes: nine bounds per pixel, three to each of three images. The
mosaic keeps each cell's bounds as three four-byte words (:func:`~percept.perception.view.mosaic.
cell_words`), and the loop takes four pixels at a time, whose twelve bytes of an image are three
aligned words: twelve word reads and nine word writes per four pixels, where a byte at a time
were 36 reads and 36 writes. The cells come first, a row at a time, in a loop of their own (float
arithmetic only). At 640x480 on the bench's turning head this
costs 0.3 ms a view where the byte-wise loop cost 0.64 ms (thread CPU time, alternating, the
same views). The words are little-endian (x86-64, ARM64).
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def bounds_in_view(
    coarse: np.ndarray,
    columns: np.ndarray,
    column_weights: np.ndarray,
    rows: np.ndarray,
    row_weights: np.ndarray,
    words: np.ndarray,
    map_rows: int,
    map_cols: int,
    lower: np.ndarray,
    upper: np.ndarray,
    moved: np.ndarray,
    model: np.ndarray,
    nearest: np.ndarray,
) -> None:
    """For each grid pixel, the cell of the map (``map_rows`` x ``map_cols``) nearest to its map
    coordinates (column, row; rounded half to even, as ``np.rint`` and ``cv2.remap``'s nearest),
    which are those of the lattice ``coarse`` (lattice rows, cols, 2) float32 interpolated
    linearly: pixel (r, c) lies between lattice columns ``columns[c]`` with float32 weights
    ``column_weights[c]`` and rows ``rows[r]`` with ``row_weights[r]`` (along the rows first, as
    ``cv2.resize``). ``words`` (cells + 1, 3) uint32 holds each cell's bounds as
    :func:`~percept.perception.view.mosaic.cell_words` packs them, its last row those of no cell.
    Into ``lower``, ``upper`` and ``moved`` (H, W, 3) uint8 (contiguous) the cell's lower,
    upper and motion bounds, into ``model`` (H, W) uint8 its brightness, into ``nearest`` (H, W)
    int32 its flat index. A pixel whose nearest cell lies outside the map (or whose coordinates
    are NaN) takes the last row's bounds, brightness 0 and index -1."""
    height, width = nearest.shape
    # The lattice rows interpolated along x (the resize's first pass), x and y apart.
    across = np.empty((coarse.shape[0], 2, width), np.float32)
    for i in range(coarse.shape[0]):
        for c in range(width):
            x0, x1 = columns[c, 0], columns[c, 1]
            a0, a1 = column_weights[c, 0], column_weights[c, 1]
            for k in range(2):
                across[i, k, c] = coarse[i, x0, k] * a0 + coarse[i, x1, k] * a1
    for r in range(height):
        above, below = across[rows[r, 0]], across[rows[r, 1]]
        b0, b1 = row_weights[r, 0], row_weights[r, 1]
        cells = nearest[r]
        for c in range(width):
            x = np.rint(above[0, c] * b0 + below[0, c] * b1)
            y = np.rint(above[1, c] * b0 + below[1, c] * b1)
            # Written so that NaN, which compares False, falls outside.
            inside = (x >= 0) & (x < map_cols) & (y >= 0) & (y < map_rows)
            cells[c] = np.int32(y) * map_cols + np.int32(x) if inside else -1
    flat, level_of = nearest.reshape(-1), model.reshape(-1)
    none = words.shape[0] - 1
    groups = len(flat) // 4
    low = lower.reshape(-1)[: 12 * groups].view(np.uint32)
    high = upper.reshape(-1)[: 12 * groups].view(np.uint32)
    bound = moved.reshape(-1)[: 12 * groups].view(np.uint32)
    bgr = np.uint32(0xFFFFFF)
    for g in range(groups):
        i = 4 * g
        a, b = words[_row(flat[i], none)], words[_row(flat[i + 1], none)]
        c, d = words[_row(flat[i + 2], none)], words[_row(flat[i + 3], none)]
        level_of[i], level_of[i + 1] = a[0] >> 24, b[0] >> 24
        level_of[i + 2], level_of[i + 3] = c[0] >> 24, d[0] >> 24
        w = 3 * g
        _four(low, w, a[0] & bgr, b[0] & bgr, c[0] & bgr, d[0] & bgr)
        _four(high, w, a[1], b[1], c[1], d[1])
        _four(bound, w, a[2], b[2], c[2], d[2])
    low8, high8, bound8 = lower.reshape(-1), upper.reshape(-1), moved.reshape(-1)
    for i in range(4 * groups, len(flat)):  # the last pixels when the count is not a multiple of 4
        cell = words[_row(flat[i], none)]
        level_of[i] = cell[0] >> 24
        for k in range(3):
            low8[3 * i + k] = (cell[0] >> (8 * k)) & 255
            high8[3 * i + k] = (cell[1] >> (8 * k)) & 255
            bound8[3 * i + k] = (cell[2] >> (8 * k)) & 255


@jit
def _row(cell: int, none: int) -> int:
    """The row of ``words`` of a cell index (-1: outside the map, row ``none``)."""
    return cell if cell >= 0 else none


@jit
def _four(out: np.ndarray, w: int, a: np.uint32, b: np.uint32, c: np.uint32, d: np.uint32) -> None:
    """Four pixels of three bytes (the low three of ``a``-``d``) as the words ``out[w:w + 3]``."""
    out[w] = a | (b << 24)
    out[w + 1] = (b >> 8) | (c << 16)
    out[w + 2] = (c >> 16) | (d << 8)
