"""Learning the unknown directions of the moving head's background from the frames.

Each frame of a turning head has a hundred or so pixels whose background is unknown; finding
them, their nearest cells and whether they were seen quietly, then adding them to the cells'
running sums, was some forty numpy calls over the whole grid and over those few pixels (0.3 ms at
640x480). Two loops do it here: :func:`fresh_samples` over the grid, :func:`accumulate` over the
samples; a third, :func:`settle`, turns the sums of the cells learned into their statistics.
Whether a pixel was quiet (no motion, outside every anchor's box) is asked only of those few
pixels, not made into a mask of the whole grid.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.tracking.motion_kernels import still_at


@jit
def fresh_samples(
    nearest: np.ndarray,
    ycc: np.ndarray,
    previous: np.ndarray,
    upper: np.ndarray,
    size: int,
    boxes: np.ndarray,
    seen: np.ndarray,
    known: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The samples of the cells not known yet: for each grid pixel not ``seen`` (H, W) bool
    against a known cell, the flat index ``nearest`` (H, W) int32 of its nearest cell of the
    map (-1: outside) when that cell is not ``known`` (flat bool), with its value ``ycc``
    (H, W, 3) and whether it was quiet: still against ``previous`` (the motion test with bounds
    ``upper`` closed with a ``size`` square, at that pixel only:
    :func:`~percept.perception.tracking.motion_kernels.still_at`) and outside every box of
    ``boxes`` (n, 4: left, top, width, height in grid pixels; a box covers
    the rows and columns from its left and top, rounded towards 0, to its right and bottom
    rounded towards 0, both included); in raster order."""
    height, width = seen.shape
    flat = np.empty(height * width, np.intp)
    values = np.empty((height * width, 3), np.uint8)
    calm = np.empty(height * width, np.bool_)
    n = 0
    for i in unseen(seen.ravel()):
        r, c = divmod(i, width)
        cell = nearest[r, c]
        if cell < 0 or known[cell]:
            continue
        quiet = still_at(ycc, previous, upper, r, c, size)
        for b in range(boxes.shape[0]):
            if not quiet:
                break
            left, top = boxes[b, 0], boxes[b, 1]
            x0, y0 = max(int(left), 0), max(int(top), 0)
            x1, y1 = int(left + boxes[b, 2]) + 1, int(top + boxes[b, 3]) + 1
            quiet = not (y0 <= r < y1 and x0 <= c < x1)
        flat[n] = cell
        values[n, 0], values[n, 1], values[n, 2] = ycc[r, c, 0], ycc[r, c, 1], ycc[r, c, 2]
        calm[n] = quiet
        n += 1
    return flat[:n], values[:n], calm[:n]


ALL_SEEN = np.uint64(0x0101010101010101)
"""Eight bools that are all True, read as one unsigned 64-bit word (a uint64: compared with a
Python int, numba would compare both as float64, which cannot tell this from its neighbours)."""


@jit
def unseen(seen: np.ndarray) -> np.ndarray:
    """Indices of the False entries of the contiguous bool array ``seen``, ascending. Read
    eight at a time: nearly all of a frame's view is known, and a loop that tests each bool
    costs ten times as much."""
    out = np.empty(len(seen), np.intp)
    n = 0
    whole = len(seen) - len(seen) % 8
    words = seen[:whole].view(np.uint64)
    for w in range(len(words)):
        if words[w] != ALL_SEEN:
            for i in range(8 * w, 8 * w + 8):
                if not seen[i]:
                    out[n] = i
                    n += 1
    for i in range(whole, len(seen)):
        if not seen[i]:
            out[n] = i
            n += 1
    return out[:n]


@jit
def accumulate(
    cells: np.ndarray,
    values: np.ndarray,
    quiet: np.ndarray,
    t: float,
    learn_time: float,
    sums: np.ndarray,
    squares: np.ndarray,
    counts: np.ndarray,
    since: np.ndarray,
) -> np.ndarray:
    """Add the ``quiet`` samples (``values`` (n, 3) of flat ``cells`` (n,)) to the running
    ``sums``, ``squares`` and ``counts`` of their cells, after restarting every cell with a
    restless sample (NaN ``since``); a cell touched for the first time is quiet ``since``
    ``t``. Returns the cells (ascending) touched now that have been quiet for ``learn_time`` with
    at least two samples. (The sums of whole numbers are exact in any order.)"""
    for i in range(len(cells)):
        if not quiet[i]:
            cell = cells[i]
            sums[cell, :] = 0.0
            squares[cell, :] = 0.0
            counts[cell] = 0
            since[cell] = np.nan
    touched = np.empty(len(cells), np.intp)
    m = 0
    for i in range(len(cells)):
        if quiet[i]:
            cell = cells[i]
            for k in range(3):
                v = float(values[i, k])
                sums[cell, k] += v
                squares[cell, k] += v * v
            counts[cell] += 1
            touched[m] = cell
            m += 1
    touched = np.unique(touched[:m])
    learned = np.empty(len(touched), np.intp)
    n = 0
    for cell in touched:
        if np.isnan(since[cell]):
            since[cell] = t
        if t - since[cell] >= learn_time and counts[cell] >= 2:
            learned[n] = cell
            n += 1
    return learned[:n]


@jit
def settle(
    cells: np.ndarray,
    sums: np.ndarray,
    squares: np.ndarray,
    counts: np.ndarray,
    since: np.ndarray,
    mean: np.ndarray,
    sigma: np.ndarray,
    known: np.ndarray,
) -> None:
    """Make the flat ``cells`` learned known: their ``mean`` and ``sigma`` (cells, 3) float32
    the mean and deviation of their running ``sums``, ``squares`` and ``counts`` (``sums / n``,
    the root of ``max(squares / n - mean**2, 0)`` in float64, as numpy computes them), and
    restart those sums."""
    for cell in cells:
        n = counts[cell]
        for k in range(3):
            m = sums[cell, k] / n
            mean[cell, k] = m
            sigma[cell, k] = np.sqrt(max(squares[cell, k] / n - m * m, 0.0))
            sums[cell, k] = 0.0
            squares[cell, k] = 0.0
        known[cell] = True
        counts[cell] = 0
        since[cell] = np.nan


@jit
def mark_cells(at: np.ndarray, nearest: np.ndarray, fg: np.ndarray, t: float) -> None:
    """``at`` (flat float per cell) becomes ``t`` at the nearest cell (``nearest`` (H, W)
    int32, -1: outside the map) of every pixel where ``fg`` (uint8 (H, W)) is 0: the
    directions seen as background (numpy's mask and scatter took a millisecond at 320x240)."""
    height, width = fg.shape
    for v in range(height):
        for u in range(width):
            cell = nearest[v, u]
            if fg[v, u] == 0 and cell >= 0:
                at[cell] = t
