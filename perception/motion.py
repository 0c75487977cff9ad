"""Motion of §4.3: pixels that changed since the previous frame by more than their noise.

A pixel moved when ``|i_c,t(p) - i_c,t-1(p)| > k_m * max(sigma_c(p), sigma_min)`` in any channel,
with ``sigma`` from the background calibration. As with the foreground, the test becomes integer
bounds for one ``cv2.inRange`` call. The mask is noise-reduced like the foreground; a model is
"in motion" when any moving pixel lies inside its predicted box.
"""

from __future__ import annotations

import cv2
import numpy as np

from perception.background import BackgroundModel


class MotionDetector:
    """Frame-differencing against the previous frame, with per-pixel thresholds."""

    def __init__(self, background: BackgroundModel, k: float, opening: int) -> None:
        self.upper = np.clip(np.floor(background.scale(k)), 0, 255).astype(np.uint8)
        self.lower = np.zeros_like(self.upper)
        self.kernel = np.ones((opening, opening), np.uint8) if opening > 1 else None
        self.previous: np.ndarray | None = None

    def update(self, ycc: np.ndarray) -> np.ndarray:
        """Motion between the previous frame and ``ycc`` as a 0/1 mask; none on the first."""
        previous, self.previous = self.previous, ycc
        if previous is None:
            return np.zeros(ycc.shape[:2], np.uint8)
        still = cv2.inRange(cv2.absdiff(ycc, previous), self.lower, self.upper)
        moved = cv2.threshold(still, 0, 1, cv2.THRESH_BINARY_INV)[1]
        return open_mask(moved, self.kernel)


def open_mask(mask: np.ndarray, kernel: np.ndarray | None) -> np.ndarray:
    """3x3 (or larger) erosion then dilation: removes specks, keeps region sizes."""
    if kernel is None:
        return mask
    return cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)


def moving_fraction(mask: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Fraction of each box ``(left, top, width, height)`` whose pixels moved (0 outside)."""
    height, width = mask.shape
    out = np.zeros(len(boxes))
    for i, (left, top, w, h) in enumerate(boxes):
        x0, y0 = max(int(left), 0), max(int(top), 0)
        x1, y1 = min(int(np.ceil(left + w)), width), min(int(np.ceil(top + h)), height)
        if x1 > x0 and y1 > y0:
            out[i] = cv2.countNonZero(mask[y0:y1, x0:x1]) / ((x1 - x0) * (y1 - y0))
    return out
