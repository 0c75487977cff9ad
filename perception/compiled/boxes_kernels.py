"""Boxes on an image, as every kernel reads them: the pixels a box covers, and whether it reaches
the image's border. Boxes are ``(left, top, width, height)`` in pixels of the image they are
laid on, floats."""

from __future__ import annotations

import math

import numpy as np

from percept.perception.compiled import jit


@jit
def pixel_span(
    left: float, top: float, width: float, height: float, image_width: int, image_height: int
) -> tuple[int, int, int, int]:
    """The pixels ``x0:x1``, ``y0:y1`` of the image that the box covers: from its left and top
    rounded towards 0 up to its right and bottom rounded up, within the image (empty when
    ``x1 <= x0`` or ``y1 <= y0``)."""
    x0, y0 = max(int(left), 0), max(int(top), 0)
    x1 = min(math.ceil(left + width), image_width)
    y1 = min(math.ceil(top + height), image_height)
    return x0, y0, x1, y1


@jit
def span_of(boxes: np.ndarray, i: int, image_width: int, image_height: int) -> tuple[int, ...]:
    """:func:`pixel_span` of box ``i`` of ``boxes`` (n, 4)."""
    return pixel_span(boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3], image_width, image_height)


@jit
def border_sides(
    left: float, top: float, width: float, height: float, image_width: int, image_height: int
) -> tuple[bool, bool, bool, bool]:
    """Whether the box reaches the outermost pixels of the image at its top, bottom, left and
    right border (its object may go on beyond them)."""
    return (
        top < 1,
        top + height > image_height - 1,
        left < 1,
        left + width > image_width - 1,
    )


@jit
def on_border(
    left: float, top: float, width: float, height: float, image_width: int, image_height: int
) -> bool:
    """Whether the box reaches the outermost pixels of the image at any of its borders
    (:func:`border_sides`): the one rule of the anchors' ``cut``, of the memory's whole
    sightings and of the agents' borders."""
    top_side, bottom, left_side, right = border_sides(
        left, top, width, height, image_width, image_height
    )
    return top_side or bottom or left_side or right
