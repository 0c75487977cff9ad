"""The bounds of the moving head's background per cell of its map, recomputed where cells were
learned (:meth:`percept.perception.view.mosaic.ViewMosaic.learn`), a tile at a time
(:func:`tiles`).

The cells learned in a frame lie in a few tiles of some sixteen cells each; as numpy and OpenCV
on each tile (the still model's bounds, their spread by erosion and dilation, the brightness,
the words) that was some thirty calls, 80 µs a tile whatever its size. Here it is one loop over
the tile and its spread, with the float32 arithmetic of
:class:`~percept.perception.segmentation.background.BackgroundModel` (the same bounds to the bit).
The spread takes the smallest lower and the largest upper bounds of the cells within ``spread`` rows
and columns, those of the map only: OpenCV's replicated border adds copies of the edge's cells,
which change neither.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def byte(value: float) -> int:
    """``value`` clipped to 0-255, as an integer (it is whole already)."""
    return int(min(max(value, 0.0), 255.0))


@jit
def cell_bounds(
    mean: np.ndarray,
    sigma: np.ndarray,
    known: np.ndarray,
    k: float,
    motion_k: float,
    sigma_min: float,
    unknown_motion: int,
    spread: int,
    box: tuple[int, int, int, int],
    brightness: np.ndarray,
    words: np.ndarray,
) -> None:
    """Write the ``brightness`` (rows, cols) uint8 and the ``words`` (rows, cols, 3) uint32 (as
    :func:`~percept.perception.view.mosaic.cell_words` packs them) of the cells of ``box`` (top,
    bottom, left, right; ends exclusive) and of those within ``spread`` of it, from the cells'
    ``mean`` and ``sigma`` (rows, cols, 3) float32 and whether they are ``known``: the bounds
    ``mean -+ k * max(sigma, sigma_min)`` rounded inwards and the motion bound
    ``motion_k * max(sigma, sigma_min)`` rounded down, in float32 (0, 255 and ``unknown_motion``
    where a cell is unknown), the lowest and highest of them within ``spread`` of each cell."""
    rows, cols = known.shape
    top, bottom, left, right = box
    y0, y1 = max(top - spread, 0), min(bottom + spread, rows)
    x0, x1 = max(left - spread, 0), min(right + spread, cols)
    py0, py1 = max(y0 - spread, 0), min(y1 + spread, rows)
    px0, px1 = max(x0 - spread, 0), min(x1 + spread, cols)
    # Each cell's own bounds over the tile and its spread, then their spread over the tile.
    own = np.empty((py1 - py0, px1 - px0, 9), np.uint8)
    kf, mk, floor = np.float32(k), np.float32(motion_k), np.float32(sigma_min)
    for y in range(py0, py1):
        for x in range(px0, px1):
            cell = own[y - py0, x - px0]
            for c in range(3):
                if known[y, x]:
                    s = max(sigma[y, x, c], floor)
                    scaled = kf * s
                    cell[c] = byte(np.ceil(mean[y, x, c] - scaled))
                    cell[3 + c] = byte(np.floor(mean[y, x, c] + scaled))
                    cell[6 + c] = byte(np.floor(mk * s))
                else:
                    cell[c], cell[3 + c], cell[6 + c] = 0, 255, unknown_motion
    low, high, moved = np.empty(3, np.int64), np.empty(3, np.int64), np.empty(3, np.int64)
    for y in range(y0, y1):
        for x in range(x0, x1):
            low[:], high[:], moved[:] = 255, 0, 0
            for v in range(max(y - spread, 0), min(y + spread + 1, rows)):
                for u in range(max(x - spread, 0), min(x + spread + 1, cols)):
                    cell = own[v - py0, u - px0]
                    for c in range(3):
                        low[c] = min(low[c], cell[c])
                        high[c] = max(high[c], cell[3 + c])
                        moved[c] = max(moved[c], cell[6 + c])
            bright = max(byte(np.rint(mean[y, x, 0])), 1) if known[y, x] else 0
            brightness[y, x] = bright
            words[y, x, 0] = low[0] | low[1] << 8 | low[2] << 16 | bright << 24
            words[y, x, 1] = high[0] | high[1] << 8 | high[2] << 16
            words[y, x, 2] = moved[0] | moved[1] << 8 | moved[2] << 16


@jit
def tiles(cells: np.ndarray, cols: int, tile: int) -> np.ndarray:
    """Boxes (m, 4: top, bottom, left, right; ends exclusive) that hold the flat indices
    ``cells`` of a map ``cols`` wide: per square ``tile`` cells wide the box of those in it,
    the tiles in raster order."""
    across = cols // tile + 1
    keys = np.empty(len(cells), np.int64)
    for i in range(len(cells)):
        y, x = divmod(cells[i], cols)
        keys[i] = (y // tile) * across + x // tile
    last = keys.max() + 1 if len(cells) else 0
    boxes = np.empty((last, 4), np.int64)
    boxes[:, 0], boxes[:, 1] = np.iinfo(np.int64).max, -1
    boxes[:, 2], boxes[:, 3] = np.iinfo(np.int64).max, -1
    for i in range(len(cells)):
        y, x = divmod(cells[i], cols)
        box = boxes[keys[i]]
        box[0], box[1] = min(box[0], y), max(box[1], y + 1)
        box[2], box[3] = min(box[2], x), max(box[3], x + 1)
    return boxes[boxes[:, 1] >= 0]
