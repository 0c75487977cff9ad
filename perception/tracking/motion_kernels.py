"""How much of each box moved (:meth:`percept.perception.tracking.motion.Motion.fraction`).

The tracker asks every frame how much moved inside the anchors' predicted boxes, and again inside
the seeds', the loose percepts' and the remembered anchors' boxes when there are any.
:func:`moved_in_boxes` answers from the two frames directly: the motion test, the noise
reduction and the count in one compiled loop over each box and the margin its noise reduction
reads, nothing outside them. When the whole mask exists already (someone looked at it),
:func:`moved_fraction` counts on it.

The noise reduction is OpenCV's ``MORPH_CLOSE`` of the "still" mask with a ``size`` x ``size``
square (anchor at ``size // 2``): a dilation, then an erosion, each over the offsets
``-size // 2 .. size - 1 - size // 2`` of every pixel, pixels outside the image taking no part
(OpenCV's default border for morphology). Both are separable into a pass along the rows and one
along the columns. A box of the image reads ``2 (size // 2)`` pixels around it, so the result
inside it is that of the whole image. The box's rows are kept as bit strings (64 pixels a word),
so a pass is a few shifts, ORs or ANDs per word (squares up to 63 pixels a side; the opening's
largest is 31); the motion test itself, three frames read row by row, is what costs.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.compiled.boxes_kernels import span_of

ONES = np.uint64(0xFFFFFFFFFFFFFFFF)
"""A word of 64 pixels all set."""

MOST = 0.25
"""The share of the image the boxes may cover, with their margins, for :func:`moved_in_boxes`
to answer between two frames of one view: beyond it OpenCV's passes over the whole image cost
less. After a head turn the previous frame must first be brought into the view, which costs
more over the whole image than the boxes' pixels do, so there the boxes cover up to all of it
(1.0; :mod:`.warp`)."""


@jit
def moved_fraction(still: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Fraction of each box ``(left, top, width, height)`` (pixels of ``still``) whose pixels
    are 0 in ``still`` (H, W), i.e. moved; 0 for a box outside the image. A box covers the
    pixels from its left and top, rounded towards 0, up to its right and bottom rounded up."""
    height, width = still.shape
    out = np.zeros(boxes.shape[0])
    for i in range(boxes.shape[0]):
        x0, y0, x1, y1 = span_of(boxes, i, width, height)
        if x1 <= x0 or y1 <= y0:
            continue
        out[i] = _share_of_zeros(still, y0, y1, x0, x1)
    return out


@jit
def moved_in_boxes(
    current: np.ndarray,
    previous: np.ndarray,
    upper: np.ndarray,
    boxes: np.ndarray,
    size: int,
    most: float,
) -> np.ndarray:
    """:func:`moved_fraction` of the "still" mask of ``current`` against ``previous`` ((H, W, 3)
    uint8 each), without the whole mask: a pixel is still where every channel changed by at
    most ``upper`` (H, W, 3), and the mask is closed with a ``size`` x ``size`` square (no noise
    reduction below 2).

    Empty (no box answered) when the boxes and their margins cover more than the share ``most``
    of the image (:data:`MOST`): a box's pixels are read row by row from the two frames and the
    bounds, at about four times the cost per pixel of OpenCV's passes over the whole image,
    which then cost less."""
    height, width = current.shape[:2]
    before = size // 2 if size > 1 else 0  # the square's offsets: -before .. +after
    after = size - 1 - before if size > 1 else 0
    if reads_too_much(boxes, size, width, height, most):
        return np.zeros(0)
    out = np.zeros(boxes.shape[0])
    for i in range(boxes.shape[0]):
        x0, y0, x1, y1 = span_of(boxes, i, width, height)
        if x1 <= x0 or y1 <= y0:
            continue
        # Below, coordinates are in the crop read, whose rows are bit strings (bit x of word
        # x // 64: pixel x is still).
        px0, py0, px1, py1 = read_span(boxes, i, size, width, height)
        still = _still_bits(current, previous, upper, py0, py1, px0, px1)
        if size > 1:
            # Outside the crop is outside the image or out of reach: it takes no part.
            still = _columns(_rows(still, px1 - px0, before, after, True), before, after, True)
            still = _columns(_rows(still, px1 - px0, before, after, False), before, after, False)
        out[i] = _share_of_zeros_bits(still, y0 - py0, y1 - py0, x0 - px0, x1 - px0)
    return out


@jit
def reads_too_much(boxes: np.ndarray, size: int, width: int, height: int, most: float) -> bool:
    """Whether the pixels :func:`moved_in_boxes` would read for ``boxes`` with a ``size`` square
    cover more than the share ``most`` of the ``width`` x ``height`` image (it then does not
    answer)."""
    return _covered(boxes, _pad(size), width, height) > most * height * width


@jit
def read_span(
    boxes: np.ndarray, i: int, size: int, width: int, height: int
) -> tuple[int, int, int, int]:
    """The pixels ``x0:x1``, ``y0:y1`` :func:`moved_in_boxes` reads for box ``i`` with a
    ``size`` square, image clipped (empty for a box outside the image): the erosion of the box
    reads the dilation around it, which reads the still mask around that."""
    x0, y0, x1, y1 = span_of(boxes, i, width, height)
    if x1 <= x0 or y1 <= y0:
        return x0, y0, x0, y0
    pad = _pad(size)
    return max(x0 - pad, 0), max(y0 - pad, 0), min(x1 + pad, width), min(y1 + pad, height)


@jit
def _pad(size: int) -> int:
    """The margin the close with a ``size`` square reads around a box."""
    return 2 * (size // 2) if size > 1 else 0


@jit
def _covered(boxes: np.ndarray, pad: int, width: int, height: int) -> int:
    """Pixels of the boxes and ``pad`` around them, inside the image (overlaps counted twice)."""
    covered = 0
    for i in range(boxes.shape[0]):
        x0, y0, x1, y1 = span_of(boxes, i, width, height)
        if x1 > x0 and y1 > y0:
            covered += (min(x1 + pad, width) - max(x0 - pad, 0)) * (
                min(y1 + pad, height) - max(y0 - pad, 0)
            )
    return covered


@jit
def _share_of_zeros(mask: np.ndarray, y0: int, y1: int, x0: int, x1: int) -> float:
    """Share of the 0 pixels of rows y0:y1, columns x0:x1 of ``mask``."""
    zeros = 0
    for y in range(y0, y1):
        for x in range(x0, x1):
            if mask[y, x] == 0:
                zeros += 1
    return zeros / ((x1 - x0) * (y1 - y0))


@jit
def still_at(
    current: np.ndarray, previous: np.ndarray, upper: np.ndarray, y: int, x: int, size: int
) -> bool:
    """The closed "still" mask of :func:`moved_in_boxes` at the one pixel (``y``, ``x``), from
    the pixels around it that the close reads: for the learning of the moving head's background,
    which asks it of the hundred or so pixels of a frame that look at unknown directions."""
    if size < 2:
        return _still_pixel(current, previous, upper, y, x)
    height, width = current.shape[:2]
    before, after = size // 2, size - 1 - size // 2
    # The erosion: every neighbour within the image is still after the dilation, that is has
    # a still neighbour within the image.
    for qy in range(max(y - before, 0), min(y + after + 1, height)):
        for qx in range(max(x - before, 0), min(x + after + 1, width)):
            if not _any_still(current, previous, upper, qy, qx, before, after):
                return False
    return True


@jit
def _any_still(
    current: np.ndarray, previous: np.ndarray, upper: np.ndarray, y: int, x: int,
    before: int, after: int,
) -> bool:  # fmt: skip
    """Whether a pixel from ``-before`` to ``+after`` around (``y``, ``x``) in the image is still
    (the dilation of the still mask there)."""
    height, width = current.shape[:2]
    for ry in range(max(y - before, 0), min(y + after + 1, height)):
        for rx in range(max(x - before, 0), min(x + after + 1, width)):
            if _still_pixel(current, previous, upper, ry, rx):
                return True
    return False


@jit
def _still_pixel(
    current: np.ndarray, previous: np.ndarray, upper: np.ndarray, y: int, x: int
) -> bool:
    """No channel of pixel (``y``, ``x``) changed by more than ``upper`` (``cv2.inRange`` of
    ``cv2.absdiff`` between 0 and ``upper``)."""
    for c in range(3):
        p, q = current[y, x, c], previous[y, x, c]
        if (np.uint8(p - q) if p >= q else np.uint8(q - p)) > upper[y, x, c]:
            return False
    return True


@jit
def _still_bits(
    current: np.ndarray, previous: np.ndarray, upper: np.ndarray, y0: int, y1: int, x0: int, x1: int
) -> np.ndarray:
    """Rows y0:y1 as bit strings of columns x0:x1: bit set where the pixel is still."""
    out = np.zeros((y1 - y0, (x1 - x0 + 63) // 64), np.uint64)
    for y in range(y0, y1):
        for x in range(x0, x1):
            if _still_pixel(current, previous, upper, y, x):
                k = x - x0
                out[y - y0, k >> 6] |= np.uint64(1) << np.uint64(k & 63)
    return out


@jit
def _rows(bits: np.ndarray, width: int, before: int, after: int, dilate: bool) -> np.ndarray:
    """Each bit the OR (``dilate``) or AND of its row's bits from ``-before`` to ``+after``
    that lie in the ``width`` bits of the row (those outside take no part)."""
    height, words = bits.shape
    out = np.empty_like(bits)
    # The bits past the row's end, as the operation needs them to take no part.
    tail = width - 64 * (words - 1)
    last = ONES if tail == 64 else (np.uint64(1) << np.uint64(tail)) - np.uint64(1)
    fill = np.uint64(0) if dilate else ONES
    for y in range(height):
        for k in range(words):
            value = bits[y, k]
            if k == words - 1:
                value = (value & last) | (fill & ~last)
            out[y, k] = value
        for k in range(words):
            acc = out[y, k]
            for o in range(-before, after + 1):
                if o != 0:
                    acc = _combine(acc, _shifted(out, y, k, o, fill), dilate)
            bits[y, k] = acc
        if dilate:
            bits[y, words - 1] &= last
    return bits


@jit
def _shifted(bits: np.ndarray, y: int, k: int, o: int, fill: np.uint64) -> np.uint64:
    """Word ``k`` of row ``y`` moved so that bit x holds bit x + ``o`` (``fill`` beyond the row)."""
    words = bits.shape[1]
    if o > 0:
        s = np.uint64(o)
        nxt = bits[y, k + 1] if k + 1 < words else fill
        return (bits[y, k] >> s) | (nxt << (np.uint64(64) - s))
    s = np.uint64(-o)
    prev = bits[y, k - 1] if k > 0 else fill
    return (bits[y, k] << s) | (prev >> (np.uint64(64) - s))


@jit
def _combine(a: np.uint64, b: np.uint64, dilate: bool) -> np.uint64:
    """``a | b`` for a dilation, ``a & b`` for an erosion."""
    return a | b if dilate else a & b


@jit
def _columns(bits: np.ndarray, before: int, after: int, dilate: bool) -> np.ndarray:
    """As :func:`_rows`, along the columns (rows outside take no part)."""
    height, words = bits.shape
    out = np.empty_like(bits)
    for y in range(height):
        for k in range(words):
            acc = bits[y, k]
            for o in range(max(-before, -y), min(after, height - 1 - y) + 1):
                acc = _combine(acc, bits[y + o, k], dilate)
            out[y, k] = acc
    return out


@jit
def _share_of_zeros_bits(bits: np.ndarray, y0: int, y1: int, x0: int, x1: int) -> float:
    """Share of the clear bits of rows y0:y1, columns x0:x1, a word at a time."""
    first, last = x0 >> 6, (x1 - 1) >> 6
    ones = 0
    for y in range(y0, y1):
        for k in range(first, last + 1):
            word = bits[y, k]
            if k == first:
                word &= ONES << np.uint64(x0 & 63)
            if k == last:
                word &= ONES >> np.uint64(63 - ((x1 - 1) & 63))
            ones += _popcount(word)
    area = (x1 - x0) * (y1 - y0)
    return (area - ones) / area


@jit
def _popcount(word: np.uint64) -> int:
    """The set bits of a word (the classic sums of bit pairs, nibbles and bytes)."""
    word = word - ((word >> np.uint64(1)) & np.uint64(0x5555555555555555))
    pairs = np.uint64(0x3333333333333333)
    word = (word & pairs) + ((word >> np.uint64(2)) & pairs)
    word = (word + (word >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return int((word * np.uint64(0x0101010101010101)) >> np.uint64(56))
