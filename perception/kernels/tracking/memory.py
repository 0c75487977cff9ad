"""How much of each box another box covers, and which boxes reach the image's border
(:mod:`percept.perception.memory`).

The anchors' memory asks every frame of a turning head how much of each anchor's box lies
inside the image and under the box of a nearer anchor: as numpy on a handful of boxes that was
some twenty calls of a few µs each, here it is one loop over the pairs, with the same float
arithmetic in the same order (the same shares to the bit, for the finite boxes it is given).
"""

from __future__ import annotations

import numpy as np

from percept.perception.kernels import jit
from percept.perception.kernels.boxes import on_border


@jit
def share(a: np.ndarray, b: np.ndarray) -> float:
    """The share of box ``a`` (left, top, width, height) that box ``b`` covers."""
    w = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    h = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    area = max(a[2] * a[3], 1e-9)
    return max(w, 0.0) * max(h, 0.0) / area


@jit
def covered(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)): the share of each box of ``a`` (n, 4) that each box of ``b`` (k, 4)
    covers."""
    out = np.empty((a.shape[0], b.shape[0]))
    for i in range(a.shape[0]):
        for j in range(b.shape[0]):
            out[i, j] = share(a[i], b[j])
    return out


@jit
def hidden_fraction(boxes: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """(n,): the largest share of each box of ``boxes`` (n, 4) under one of the boxes ``seen``
    (k, 4) whose lower edge is lower (the nearer objects); 0 under none."""
    out = np.zeros(boxes.shape[0])
    for i in range(boxes.shape[0]):
        bottom = boxes[i, 1] + boxes[i, 3]
        for j in range(seen.shape[0]):
            if seen[j, 1] + seen[j, 3] > bottom:
                out[i] = max(out[i], share(boxes[i], seen[j]))
    return out


@jit
def touches_border(boxes: np.ndarray, width: int, height: int) -> np.ndarray:
    """:func:`~percept.perception.kernels.boxes.on_border` of each box of ``boxes`` (n, 4)."""
    out = np.empty(boxes.shape[0], np.bool_)
    for i in range(boxes.shape[0]):
        out[i] = on_border(boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3], width, height)
    return out
