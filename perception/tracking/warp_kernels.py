"""The previous frame brought into the current view, only where the motion is read.

When the head turned, motion (SPEC §4.3) compares a frame with the previous one brought into its
view through the homography of the turn. ``cv2.warpPerspective`` brought the whole previous frame
(0.28 ms for the 320x240 grid of 640x480, 0.33 ms with the conversions to four channels and back
that make OpenCV's warp fast), but the motion is read only in the boxes the tracker asks about
(:func:`~percept.perception.tracking.motion_kernels.moved_in_boxes`, with the margin its noise
reduction reads) and around the few pixels the learning of unknown directions asks about
(:func:`~percept.perception.tracking.motion_kernels.still_at`). :func:`warp_boxes` and
:func:`warp_near` bring just those pixels, :func:`warp_all` every pixel (the whole mask).

Every pixel is brought by the one function :func:`_bring`, so that a pixel has the same value
whichever of the three brought it (its value depends on its coordinates alone): the point the
inverse homography maps it to, in float64, taken to 32nds of a pixel, and the bilinear weights of
its four pixels of the previous frame in those 32nds, in integers, as OpenCV's fixed-point warp
did before version 4.11. Where those four are not all inside the previous frame (it did not see
the point, or saw it at its very edge), the pixel keeps the current frame's value: it counts as
not moved. OpenCV 5's warp (float32 arithmetic, the current frame's value mixed in at the edge)
gives values within a grey level or two of these on a smooth image
(tests/perception/test_kernels.py).
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.tracking.motion_kernels import read_span, reads_too_much
from percept.perception.view.learning_kernels import unseen

BITS = 5
"""The fraction of a pixel's position kept: 32nds."""
SUB = 1 << BITS
HALF = 1 << (2 * BITS - 1)
"""Half the weights' sum (``SUB`` squared): rounds the weighted sum to the nearest grey level."""


@jit
def warp_boxes(
    previous: np.ndarray,
    current: np.ndarray,
    inverse: np.ndarray,
    boxes: np.ndarray,
    size: int,
    most: float,
    out: np.ndarray,
) -> bool:
    """Bring into ``out`` (H, W, 3) uint8 the pixels that
    :func:`~percept.perception.tracking.motion_kernels.moved_in_boxes` reads for ``boxes`` (n, 4)
    with a ``size`` square: ``previous`` seen through ``inverse`` (3x3 float64, from the current
    view's pixels to the previous one's), ``current`` where it has nothing. False, and nothing
    brought, when ``moved_in_boxes`` would not answer (the boxes cover more than ``most``)."""
    height, width = current.shape[:2]
    if reads_too_much(boxes, size, width, height, most):
        return False
    scratch = np.empty((3, width), np.int32)
    for i in range(boxes.shape[0]):
        x0, y0, x1, y1 = read_span(boxes, i, size, width, height)
        for y in range(y0, y1):
            _bring(previous, current, inverse, y, x0, x1, out, scratch)
    return True


@jit
def warp_near(
    previous: np.ndarray,
    current: np.ndarray,
    inverse: np.ndarray,
    seen: np.ndarray,
    size: int,
    out: np.ndarray,
) -> None:
    """Bring into ``out`` (as :func:`warp_boxes`) the pixels that
    :func:`~percept.perception.tracking.motion_kernels.still_at` reads for every pixel not
    ``seen`` (H, W) bool (those the learning of unknown directions asks about): those within
    twice the square's reach (the close's erosion reads the dilation around the pixel, which
    reads the pixels around that)."""
    height, width = seen.shape
    before = size // 2 if size > 1 else 0
    after = size - 1 - before if size > 1 else 0
    needed = np.zeros((height, width), np.bool_)
    scratch = np.empty((3, width), np.int32)
    for i in unseen(seen.ravel()):
        y, x = divmod(i, width)
        needed[max(y - 2 * before, 0) : y + 2 * after + 1,
               max(x - 2 * before, 0) : x + 2 * after + 1] = True  # fmt: skip
    for y in range(height):
        x = 0
        while x < width:
            if not needed[y, x]:
                x += 1
                continue
            end = x
            while end < width and needed[y, end]:
                end += 1
            _bring(previous, current, inverse, y, x, end, out, scratch)
            x = end


@jit
def warp_all(
    previous: np.ndarray, current: np.ndarray, inverse: np.ndarray, out: np.ndarray
) -> None:
    """Bring every pixel into ``out`` (as :func:`warp_boxes`)."""
    height, width = current.shape[:2]
    scratch = np.empty((3, width), np.int32)
    for y in range(height):
        _bring(previous, current, inverse, y, 0, width, out, scratch)


@jit
def _bring(
    previous: np.ndarray,
    current: np.ndarray,
    inverse: np.ndarray,
    y: int,
    x0: int,
    x1: int,
    out: np.ndarray,
    scratch: np.ndarray,
) -> None:
    """Pixels ``x0:x1`` of row ``y`` of the current view from ``previous`` through ``inverse``
    (``scratch``: (3, W) int32 the caller's, allocated once for all its rows). A pixel's value
    depends on its coordinates alone, not on the run it is brought in.

    Two loops: the first maps the run's pixels to the previous frame, without branches, so that
    LLVM vectorises it (the divisions above all); the second reads and weighs their four pixels.
    One loop doing both cost 16 ns a pixel against 9 (the 320x240 grid, thread CPU time)."""
    height, width = previous.shape[:2]
    source, here, there = previous.reshape(-1), current.reshape(-1), out.reshape(-1)
    fy = float(y)
    row_x = inverse[0, 1] * fy + inverse[0, 2]
    row_y = inverse[1, 1] * fy + inverse[1, 2]
    row_w = inverse[2, 1] * fy + inverse[2, 2]
    n = x1 - x0
    first = scratch[0]  # offset of the upper left pixel in ``source``; -1: none
    across, down = scratch[1], scratch[2]  # the point's fractions, in 32nds
    for j in range(n):
        fx = float(x0 + j)
        w = inverse[2, 0] * fx + row_w
        ahead = w > 0  # else the point lies on or behind the previous camera's plane
        w = w if ahead else 1.0
        sx, sy = (inverse[0, 0] * fx + row_x) / w, (inverse[1, 0] * fx + row_y) / w
        # Written so that NaN and the infinities of a point far off fall outside.
        near = ahead & (sx > -1.0) & (sy > -1.0) & (sx < width) & (sy < height)
        # The point in 32nds of a pixel (as OpenCV's fixed-point warp took it), rounded half
        # up (the truncation of a positive number).
        X = np.int32((sx + 1.0) * SUB + 0.5) - SUB if near else -SUB
        Y = np.int32((sy + 1.0) * SUB + 0.5) - SUB if near else -SUB
        ix, iy = X >> BITS, Y >> BITS
        inside = (ix >= 0) & (ix < width - 1) & (iy >= 0) & (iy < height - 1)
        first[j] = 3 * (iy * width + ix) if inside else -1
        across[j], down[j] = X & (SUB - 1), Y & (SUB - 1)
    for j in range(n):
        s, k = first[j], 3 * (y * width + x0 + j)
        if s < 0:
            for c in range(3):
                there[k + c] = here[k + c]
            continue
        ax, ay = across[j], down[j]
        w00, w01 = (SUB - ax) * (SUB - ay), ax * (SUB - ay)
        w10, w11 = (SUB - ax) * ay, ax * ay
        below = s + 3 * width
        for c in range(3):
            value = (
                w00 * np.int32(source[s + c])
                + w01 * np.int32(source[s + 3 + c])
                + w10 * np.int32(source[below + c])
                + w11 * np.int32(source[below + 3 + c])
            )
            there[k + c] = np.uint8((value + HALF) >> (2 * BITS))
