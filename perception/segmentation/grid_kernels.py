"""The grid of every ``step``-th pixel of every ``step``-th row
(:func:`percept.perception.segmentation.labelling.regions.subsample`).

A 640x480 camera frame arrives from the driver (or the renderer) outside the processor's cache;
taking its grid is reading every second row of it. ``cv2.resize`` with nearest-neighbour
interpolation picks the same pixels; on the bench's 640x480 frames (``bench/bench_perception.py
--steps``, "taking the grid") it took 164-218 µs a frame, this loop 64-85 the same evening.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def every_step(rows: np.ndarray, step: int, channels: int) -> np.ndarray:
    """Every ``step``-th pixel of every ``step``-th row of an image given as its rows of bytes
    (H, W * ``channels``), as rows of bytes (ceil(H / step), ceil(W / step) * ``channels``)."""
    height, width = rows.shape[0], rows.shape[1] // channels
    h, w = (height + step - 1) // step, (width + step - 1) // step
    out = np.empty((h, w * channels), np.uint8)
    if step == 2 and channels == 3:
        # The grid of a 640x480 colour frame: with the strides known the compiler vectorises
        # the copy (three times as fast as the general loop below).
        for y in range(h):
            for x in range(w):
                out[y, 3 * x] = rows[2 * y, 6 * x]
                out[y, 3 * x + 1] = rows[2 * y, 6 * x + 1]
                out[y, 3 * x + 2] = rows[2 * y, 6 * x + 2]
        return out
    for y in range(h):
        for x in range(w):
            for k in range(channels):
                out[y, channels * x + k] = rows[step * y, channels * step * x + k]
    return out
