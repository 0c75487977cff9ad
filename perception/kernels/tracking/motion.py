"""How much of each box moved (:meth:`percept.perception.motion.Motion.fraction`), counted on
the frame's noise-reduced "still" mask in one compiled loop over the boxes."""

from __future__ import annotations

import math

import numpy as np

from percept.perception.kernels import jit


@jit
def moved_fraction(still: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Fraction of each box ``(left, top, width, height)`` (pixels of ``still``) whose pixels
    are 0 in ``still`` (H, W), i.e. moved; 0 for a box outside the image. A box covers the
    pixels from its left and top, rounded towards 0, up to its right and bottom rounded up."""
    height, width = still.shape
    out = np.zeros(boxes.shape[0])
    for i in range(boxes.shape[0]):
        left, top = boxes[i, 0], boxes[i, 1]
        x0, y0 = max(int(left), 0), max(int(top), 0)
        x1 = min(math.ceil(left + boxes[i, 2]), width)
        y1 = min(math.ceil(top + boxes[i, 3]), height)
        if x1 <= x0 or y1 <= y0:
            continue
        moved = 0
        for y in range(y0, y1):
            for x in range(x0, x1):
                if still[y, x] == 0:
                    moved += 1
        out[i] = moved / ((x1 - x0) * (y1 - y0))
    return out
