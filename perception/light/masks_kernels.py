"""The light adaptation's masks of :mod:`percept.perception.light.maintenance`: the anchors'
boxes on the grid, the time each pixel was last busy, and the share of the foreground outside the
anchors. A loop over a handful of boxes, one over the pixels that writes only where the mask
holds, and one over the sparse grid, where numpy spent a few µs per box, a boolean copy of the
mask, and five calls on the sparse grid."""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.compiled.boxes_kernels import pixel_span


@jit
def box_mask(boxes: np.ndarray, height: int, width: int, step: int) -> np.ndarray:
    """Bool (height, width) of a grid of ``step``: True inside any of the ``boxes`` ((n, 4)
    float: left, top, width, height in image pixels)."""
    mask = np.empty((height, width), np.bool_)
    paint_boxes(boxes, step, mask)
    return mask


@jit
def paint_boxes(boxes: np.ndarray, step: int, mask: np.ndarray) -> None:
    """:func:`box_mask` into ``mask`` (bool (H, W)), which it overwrites."""
    height, width = mask.shape
    mask[:] = False
    for i in range(boxes.shape[0]):
        left, top, w, h = (
            boxes[i, 0] / step,
            boxes[i, 1] / step,
            boxes[i, 2] / step,
            boxes[i, 3] / step,
        )
        x0, y0, x1, y1 = pixel_span(left, top, w, h, width, height)
        for v in range(y0, y1):
            for u in range(x0, x1):
                mask[v, u] = True


@jit
def mark(busy: np.ndarray, where: np.ndarray, t: float, on: bool) -> None:
    """``busy`` (float (H, W)) becomes ``t`` where ``where`` (uint8 (H, W)) is not 0 (``on``)
    or is 0 (not ``on``)."""
    height, width = where.shape
    for v in range(height):
        for u in range(width):
            if (where[v, u] != 0) == on:
                busy[v, u] = t


@jit
def mark_frame(raw: np.ndarray, background_at: np.ndarray, busy: np.ndarray, t: float) -> None:
    """Of a frame at time ``t`` with the 0/1 foreground ``raw`` (uint8 (H, W)): where it is 0,
    ``background_at`` (float (H, W)) becomes ``t``, elsewhere ``busy`` (alike) does; as
    :func:`mark` twice, in one pass."""
    height, width = raw.shape
    for v in range(height):
        for u in range(width):
            if raw[v, u] == 0:
                background_at[v, u] = t
            else:
                busy[v, u] = t


@jit
def share_outside(mask: np.ndarray, excluded: np.ndarray, step: int) -> float:
    """Share of the pixels of every ``step``-th row and column outside ``excluded`` (bool
    (H, W)) where ``mask`` (uint8 (H, W)) is not 0; 0 when all are excluded."""
    height, width = mask.shape
    inside = seen = 0
    for v in range(0, height, step):
        for u in range(0, width, step):
            if not excluded[v, u]:
                seen += 1
                inside += mask[v, u] != 0
    return inside / seen if seen else 0.0
