"""Motion of §4.3: pixels that changed since the previous frame by more than their noise.

A pixel moved when ``|i_c,t(p) - i_c,t-1(p)| > k_m * max(sigma_c(p), sigma_min)`` in any channel,
with ``sigma`` from the background calibration. As with the foreground, the test becomes integer
bounds for one ``cv2.inRange`` call, and the mask is noise-reduced like the foreground.

The perception core only asks how much moved inside a few boxes (the anchors' predicted boxes,
the seeds', the loose percepts'), so :class:`Motion` answers that from the two frames inside the
boxes and the margin their noise reduction reads, in one compiled loop
(:func:`percept.perception.tracking.motion_kernels.moved_in_boxes`), the same to the pixel as
the whole mask. The whole mask is built when someone looks at it (the maintenance of the light,
a debug view), or when the boxes cover more than a quarter of the image (all of it after a head
turn: :data:`~percept.perception.tracking.motion_kernels.MOST`); from then on the boxes are
counted on it. The learning of the moving head's background asks about single pixels
(:meth:`Motion.per_pixel`). When the head turned, the previous frame is brought into the current
view (:mod:`percept.perception.tracking.warp_kernels`) only where the boxes or those pixels read
it, the whole of it for the whole mask. On the bench's scene
(``bench/bench_perception.py --steps``, "motion in boxes") the boxes alone cost 27-46 µs a frame
at 176x144 and 63-96 at 640x480 (a 320x240 grid), the whole mask and its count 64-68 and 150-183.

On the grid of the regions (``step`` s > 1, see
:mod:`percept.perception.segmentation.labelling.regions`) the frames are the grid of every s-th
pixel of every s-th row, and the noise reduction works on that grid.
"""

from __future__ import annotations

import cv2
import numpy as np

from percept.perception.segmentation.background import BackgroundModel
from percept.perception.tracking.motion_kernels import MOST, moved_fraction, moved_in_boxes
from percept.perception.tracking.warp_kernels import warp_all, warp_boxes, warp_near


class Motion:
    """The motion between two frames (or their grids), evaluated where asked."""

    def __init__(
        self,
        current: np.ndarray,
        previous: np.ndarray | None,
        bounds: tuple[np.ndarray, np.ndarray],
        kernel: np.ndarray | None,
        step: int = 1,
        turn: np.ndarray | None = None,
    ) -> None:
        """``turn``: the homography (3x3) from the pixels of ``previous`` to those of ``current``
        when the camera turned between them (None: the same view)."""
        self.current, self.previous = current, previous
        self.lower, self.upper = bounds
        self.kernel = kernel
        self.step = step
        self.size = 0 if kernel is None else len(kernel)
        self._inverse = None if turn is None or previous is None else np.linalg.inv(turn)
        self._in_view: np.ndarray | None = None
        """The previous frame brought into this view where asked so far (:mod:`percept.
        perception.tracking.warp_kernels`); its other pixels are not set."""
        self._whole_in_view = False
        self._still_mask: np.ndarray | None = None

    def fraction(self, boxes: np.ndarray) -> np.ndarray:
        """Fraction of each box ``(left, top, width, height)`` (image pixels) whose pixels moved
        (0 outside the image)."""
        if self.previous is None or len(boxes) == 0:
            return np.zeros(len(boxes))
        if self.step > 1:
            boxes = boxes / self.step
        boxes = np.ascontiguousarray(boxes, dtype=np.float64)
        if self._still_mask is None:
            most = MOST if self._inverse is None else 1.0  # see MOST
            previous = self._boxes_in_view(boxes, most)
            if previous is not None:
                out = moved_in_boxes(self.current, previous, self.upper, boxes, self.size, most)
                if len(out) == len(boxes):
                    return out
        return moved_fraction(self._whole_still(), boxes)

    def previous_in_one_view(self) -> np.ndarray | None:
        """The previous frame when :meth:`fraction` counts boxes between it and :attr:`current`
        as they are (:func:`moved_in_boxes` with :data:`MOST`), which a compiled caller may do
        itself (:func:`~percept.perception.tracking.update_kernels.track`); None on the first
        frame, after a turn and once the whole mask is made: then :meth:`fraction` answers."""
        return self.previous if self._inverse is None and self._still_mask is None else None

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

    def per_pixel(self, seen: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """``(previous, upper, size)`` for a kernel that asks about the pixels not ``seen``
        (H, W) bool only (:func:`~percept.perception.tracking.motion_kernels.still_at`, with
        :attr:`current`): the previous frame in this view around those pixels (this one on the
        first frame: nothing moved), the bounds of the difference and the side of the noise
        reduction's square."""
        if self.previous is None:
            return self.current, self.upper, self.size
        if self._inverse is None or self._whole_in_view:
            return self._previous_in_view(), self.upper, self.size
        warp_near(self.previous, self.current, self._inverse, seen, self.size, self._buffer())
        return self._buffer(), self.upper, self.size

    def _boxes_in_view(self, boxes: np.ndarray, most: float) -> np.ndarray | None:
        """The previous frame in this view where :func:`moved_in_boxes` reads ``boxes`` (grid
        pixels), or None when they read more than the share ``most`` of it (the whole mask is
        cheaper)."""
        if self._inverse is None:
            return self.previous
        assert self.previous is not None
        inverse, size = self._inverse, self.size
        if warp_boxes(self.previous, self.current, inverse, boxes, size, most, self._buffer()):
            return self._buffer()
        return None

    def _previous_in_view(self) -> np.ndarray:
        """The whole previous frame brought into this view."""
        assert self.previous is not None
        if self._inverse is None:
            return self.previous
        if not self._whole_in_view:
            warp_all(self.previous, self.current, self._inverse, self._buffer())
            self._whole_in_view = True
        return self._buffer()

    def _buffer(self) -> np.ndarray:
        if self._in_view is None:
            self._in_view = np.empty_like(self.current)
        return self._in_view

    def _whole_still(self) -> np.ndarray:
        """The whole "still" mask, noise-reduced: closing it is opening the "moved" mask
        (erosion then dilation), with the same treatment of the image border."""
        if self._still_mask is None:
            if self.previous is None:
                raise RuntimeError("motion needs a previous frame; callers handle the first frame")
            diff = cv2.absdiff(self.current, self._previous_in_view())
            still = cv2.inRange(diff, self.lower, self.upper)
            if self.kernel is not None:
                still = cv2.morphologyEx(still, cv2.MORPH_CLOSE, self.kernel)
            self._still_mask = still
        return self._still_mask


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
        self, ycc: np.ndarray, turn: np.ndarray | None = None, upper: np.ndarray | None = None
    ) -> Motion:
        """The motion from the previous frame to ``ycc`` (none for the first frame).

        When the camera turned, ``turn`` is the homography from the previous frame's (grid)
        pixels to this one's, and ``upper`` are the difference bounds of this view (the
        calibration's otherwise).
        """
        bounds = self.bounds if upper is None else (self.bounds[0], upper)
        motion = Motion(ycc, self.previous, bounds, self.kernel, self.step, turn)
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
