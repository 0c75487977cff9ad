"""How much of each box another box covers, which boxes reach the image's border, and where the
feet of boxes stand on the ground (:mod:`percept.perception.tracking.permanence.memory`).

The anchors' memory asks every frame of a turning head how much of each anchor's box lies
inside the image and under the box of a nearer anchor, and where the anchors seen stand: as
numpy on a handful of boxes that was some forty calls of a few µs each, here it is a few loops,
with the same float arithmetic in the same order (the same results to the bit, for the finite
boxes it is given). The feet's rays and ground points stay those of :mod:`percept.kinematics`
(one implementation of the camera's geometry; compiled twins of them saved some 20 µs a frame).
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.compiled.boxes_kernels import on_border


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
def sight(
    boxes: np.ndarray,
    seen: np.ndarray,
    cut: np.ndarray,
    width: int,
    height: int,
    touching: float,
    out_of_sight: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """How each of the anchors' ``boxes`` (n, 4) was seen in a ``width`` x ``height`` image,
    by which were ``seen`` and which of those ``cut`` by its border, and the share of each
    under the boxes seen of nearer anchors (:func:`hidden_fraction`): (n,) bool each, whether
    it was seen whole (not cut, less than ``touching`` hidden), roughly (not cut, not whole,
    less than ``out_of_sight`` hidden), cut (less than ``out_of_sight`` hidden), and whether it
    is out of sight (less than ``out_of_sight`` of it inside the image, or that much hidden)."""
    hidden = hidden_fraction(boxes, boxes[seen])
    inside = inside_fraction(boxes, width, height)
    n = boxes.shape[0]
    whole, rough = np.zeros(n, np.bool_), np.zeros(n, np.bool_)
    glimpsed, away = np.zeros(n, np.bool_), np.zeros(n, np.bool_)
    for i in range(n):
        clear = hidden[i] < out_of_sight
        if seen[i] and not cut[i]:
            whole[i] = hidden[i] < touching
            rough[i] = not whole[i] and clear
        glimpsed[i] = seen[i] and cut[i] and clear
        away[i] = inside[i] < out_of_sight or not clear
    return whole, rough, glimpsed, away


@jit
def inside_fraction(boxes: np.ndarray, width: int, height: int) -> np.ndarray:
    """Share (n,) of each of ``boxes`` (n, 4) inside a ``width`` x ``height`` image (its pixels'
    edges: from -0.5 to the width and height less a half)."""
    image = np.array([-0.5, -0.5, float(width), float(height)])
    out = np.empty(boxes.shape[0])
    for i in range(boxes.shape[0]):
        out[i] = share(boxes[i], image)
    return out


@jit
def touches_border(boxes: np.ndarray, width: int, height: int) -> np.ndarray:
    """:func:`~percept.perception.compiled.boxes_kernels.on_border` of each box of ``boxes``
    (n, 4)."""
    out = np.empty(boxes.shape[0], np.bool_)
    for i in range(boxes.shape[0]):
        out[i] = on_border(boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3], width, height)
    return out


@jit
def feet(boxes: np.ndarray) -> np.ndarray:
    """The pixels (n, 2) of the middles of the lower edges of ``boxes`` (n, 4), with the
    arithmetic of :func:`~percept.perception.features.experience.bbox_edge_pixels`."""
    out = np.empty((boxes.shape[0], 2))
    for i in range(boxes.shape[0]):
        left, top, width, height = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        out[i, 0] = ((left - 0.5) + (left + width - 0.5)) / 2
        out[i, 1] = top + height - 0.5
    return out


@jit
def reaches(xy: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Metres (n,) from ``t`` (3,) to the ground points ``xy`` (n, 2; NaN gives NaN), summed
    as numpy's norm of the rows sums them."""
    out = np.empty(xy.shape[0])
    for i in range(xy.shape[0]):
        dx, dy, dz = xy[i, 0] - t[0], xy[i, 1] - t[1], 0.0 - t[2]
        out[i] = np.sqrt(dx * dx + dy * dy + dz * dz)
    return out
