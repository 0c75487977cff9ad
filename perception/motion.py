"""Motion of §4.3: pixels that changed since the previous frame by more than their noise.

A pixel moved when ``|i_c,t(p) - i_c,t-1(p)| > k_m * max(sigma_c(p), sigma_min)`` in any channel,
with ``sigma`` from the background calibration. As with the foreground, the test becomes integer
bounds for one ``cv2.inRange`` call, and the mask is noise-reduced like the foreground.

The perception core only asks how much moved inside a few boxes (a model's predicted box, a seed's
box), so :class:`Motion` answers that on crops of the two frames, padded so that the noise reduction
inside the box is exactly that of the whole image. The whole mask is built only when someone looks
at it, or when the image is small enough that one pass over it costs less. At 640x480 with 8 boxes
the crops cost about a third of a pass over the whole image. The moved pixels of the boxes are
counted in one compiled loop (:mod:`percept.perception.kernels.tracking.motion`): at 176x144 with 8
objects a Python loop of crops and counts cost more than the mask itself.

On the grid of the regions (``step`` s > 1, see :mod:`percept.perception.regions`) the frames are
the grid of every s-th pixel of every s-th row, and the noise reduction works on that grid.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

from percept.perception.background import BackgroundModel
from percept.perception.kernels.tracking.motion import moved_fraction

FULL_FRAME_PIXELS = 320 * 240
"""Up to this image size one pass over the whole image costs less than a few crops."""
MANY_BOXES = 32
"""From this many boxes on, one pass over the whole image costs less than their crops."""


class Motion:
    """The motion between two frames (or their grids), evaluated where asked."""

    def __init__(
        self,
        current: np.ndarray,
        previous: np.ndarray | None,
        bounds: tuple[np.ndarray, np.ndarray],
        kernel: np.ndarray | None,
        step: int = 1,
    ) -> None:
        self.current, self.previous = current, previous
        self.lower, self.upper = bounds
        self.kernel = kernel
        self.step = step
        self.pad = 0 if kernel is None else 2 * (len(kernel) // 2)
        self._still_mask: np.ndarray | None = None

    def fraction(self, boxes: np.ndarray) -> np.ndarray:
        """Fraction of each box ``(left, top, width, height)`` (image pixels) whose pixels moved
        (0 outside the image)."""
        if self.previous is None or len(boxes) == 0:
            return np.zeros(len(boxes))
        if self.step > 1:
            boxes = boxes / self.step
        boxes = np.ascontiguousarray(boxes, dtype=np.float64)
        height, width = self.current.shape[:2]
        if (
            self._still_mask is not None
            or height * width <= FULL_FRAME_PIXELS
            or len(boxes) >= MANY_BOXES
        ):
            return moved_fraction(self._whole_still(), boxes)
        out = np.zeros(len(boxes))
        pad = self.pad
        for i, (left, top, w, h) in enumerate(boxes.tolist()):
            x0, y0 = max(int(left), 0), max(int(top), 0)
            x1, y1 = min(math.ceil(left + w), width), min(math.ceil(top + h), height)
            if x1 <= x0 or y1 <= y0:
                continue
            px0, py0 = max(x0 - pad, 0), max(y0 - pad, 0)
            still = self._still(py0, min(y1 + pad, height), px0, min(x1 + pad, width))
            out[i] = moved_fraction(still, np.array([[x0 - px0, y0 - py0, x1 - x0, y1 - y0]]))[0]
        return out

    def mask(self) -> np.ndarray:
        """The (H, W) 0/1 motion mask (of the grid when ``step`` > 1) after noise reduction;
        zeros on the first frame."""
        return cv2.threshold(self.still(), 0, 1, cv2.THRESH_BINARY_INV)[1]

    def still(self) -> np.ndarray:
        """The (H, W) uint8 "still" mask (of the grid when ``step`` > 1): 0 where something
        moved, after noise reduction, 255 elsewhere; all 255 on the first frame."""
        if self.previous is None:
            return np.full(self.current.shape[:2], 255, np.uint8)
        return self._whole_still()

    def _whole_still(self) -> np.ndarray:
        if self._still_mask is None:
            self._still_mask = self._still(0, self.current.shape[0], 0, self.current.shape[1])
        return self._still_mask

    def _still(self, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        """255 where nothing moved inside rows y0:y1 and columns x0:x1, noise-reduced.

        Closing the "still" mask is opening the "moved" mask (erosion then dilation), with the
        same treatment of the image border.
        """
        if self.previous is None:
            raise RuntimeError("motion needs a previous frame; callers handle the first frame")
        diff = cv2.absdiff(self.current[y0:y1, x0:x1], self.previous[y0:y1, x0:x1])
        still = cv2.inRange(diff, self.lower[y0:y1, x0:x1], self.upper[y0:y1, x0:x1])
        if self.kernel is None:
            return still
        return cv2.morphologyEx(still, cv2.MORPH_CLOSE, self.kernel)


class MotionDetector:
    """Keeps the previous frame and the thresholds.

    ``background`` is the model of the frames given to :meth:`update`; they are the grid of
    every ``step``-th pixel of the image when ``step`` > 1 (boxes are asked in image pixels).
    """

    def __init__(self, background: BackgroundModel, k: float, opening: int, step: int = 1) -> None:
        upper = np.clip(np.floor(background.scale(k)), 0, 255).astype(np.uint8)
        self.bounds = (np.zeros_like(upper), upper)
        self.kernel = opening_kernel(opening)
        self.step = step
        self.previous: np.ndarray | None = None

    def update(
        self,
        ycc: np.ndarray,
        into_view: Callable[[np.ndarray], np.ndarray] | None = None,
        upper: np.ndarray | None = None,
    ) -> Motion:
        """The motion from the previous frame to ``ycc`` (none for the first frame).

        When the camera moved, ``into_view`` brings the previous frame into this frame's view,
        and ``upper`` are the difference bounds of this view (the calibration's otherwise).
        """
        previous = self.previous
        if previous is not None and into_view is not None:
            previous = into_view(previous)
        bounds = self.bounds if upper is None else (self.bounds[0], upper)
        motion = Motion(ycc, previous, bounds, self.kernel, self.step)
        self.previous = ycc
        return motion


def opening_kernel(size: int) -> np.ndarray | None:
    """The ``size`` x ``size`` kernel of :func:`open_mask` (None, no noise reduction, below 2)."""
    return np.ones((size, size), np.uint8) if size > 1 else None


def open_mask(mask: np.ndarray, kernel: np.ndarray | None) -> np.ndarray:
    """Erosion then dilation with ``kernel`` (3x3 in the chapter): removes specks."""
    if kernel is None:
        return mask
    return cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
