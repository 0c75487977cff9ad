"""The common alternative that percept is measured against: OpenCV MOG2 + a blob tracker.

Per frame: ``BackgroundSubtractorMOG2.apply`` (shadows, marked 127, count as background), a 3x3
opening, ``connectedComponentsWithStats``, then a SORT-style tracker of box centres: one filterpy
``KalmanFilter`` (constant velocity, state cx, cy, vx, vy) per track, Hungarian assignment
(scipy) on centre distance with a gate, a new track for every unmatched blob, and deletion after
``max_age`` frames without a match. Box size is taken from the last matched blob. Tracks are
reported in frames in which they were matched, like percept's visible anchors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.optimize import linear_sum_assignment


@dataclass
class _Track:
    id: int
    kf: KalmanFilter
    size: tuple[float, float]
    misses: int = 0
    seen: bool = field(default=True)


class BlobTracker:
    """Kalman-filtered box centres with Hungarian association."""

    def __init__(self, width: int, height: int, gate: float = 0.1, max_age: int = 25) -> None:
        self.gate = gate * math.hypot(width, height)
        self.max_age = max_age
        self.tracks: list[_Track] = []
        self._next = 1

    def _new(self, box: np.ndarray) -> _Track:
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.F = np.array([[1, 0, 1, 0], [0, 1, 0, 1], [0, 0, 1, 0], [0, 0, 0, 1]], float)
        kf.H = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], float)
        kf.P *= 10.0
        kf.Q = np.eye(4) * 0.1
        kf.R = np.eye(2) * 1.0
        kf.x[:2, 0] = box[:2] + box[2:] / 2
        track = _Track(self._next, kf, (float(box[2]), float(box[3])))
        self._next += 1
        return track

    def update(self, boxes: np.ndarray) -> list[tuple[int, float, float, float, float]]:
        """Track ``boxes`` (left, top, width, height); (id, left, top, w, h) of matched tracks."""
        for track in self.tracks:
            track.kf.predict()
            track.seen = False
        centres = boxes[:, :2] + boxes[:, 2:] / 2
        matched = set()
        if self.tracks and len(boxes):
            predicted = np.array([t.kf.x[:2, 0] for t in self.tracks])
            cost = np.linalg.norm(predicted[:, None] - centres[None], axis=2)
            for ti, di in zip(*linear_sum_assignment(cost), strict=True):
                if cost[ti, di] <= self.gate:
                    track = self.tracks[ti]
                    track.kf.update(centres[di])
                    track.size = (float(boxes[di, 2]), float(boxes[di, 3]))
                    track.misses, track.seen = 0, True
                    matched.add(int(di))
        for track in self.tracks:
            if not track.seen:
                track.misses += 1
        self.tracks = [t for t in self.tracks if t.misses <= self.max_age]
        self.tracks += [self._new(boxes[i]) for i in range(len(boxes)) if i not in matched]
        out = []
        for t in self.tracks:
            if t.seen:
                cx, cy = t.kf.x[0, 0], t.kf.x[1, 0]
                out.append((t.id, cx - t.size[0] / 2, cy - t.size[1] / 2, *t.size))
        return out


class Mog2Tracker:
    """MOG2 foreground, 3x3 opening, connected components, :class:`BlobTracker`."""

    def __init__(self, width: int, height: int, min_area: float = 0.0005) -> None:
        self.mog = cv2.createBackgroundSubtractorMOG2()
        self.kernel = np.ones((3, 3), np.uint8)
        self.min_pixels = min_area * width * height
        self.tracker = BlobTracker(width, height)

    def foreground(self, frame_bgr: np.ndarray) -> np.ndarray:
        """0/255 foreground after the opening (shadows removed)."""
        mask = self.mog.apply(frame_bgr)
        mask = cv2.threshold(mask, 200, 255, cv2.THRESH_BINARY)[1]
        return cv2.morphologyEx(mask, cv2.MORPH_OPEN, self.kernel)

    def learn(self, frames: list[np.ndarray]) -> None:
        """Feed frames to MOG2 without tracking (its counterpart of calibration)."""
        for frame in frames:
            self.mog.apply(frame)

    def process(self, frame_bgr: np.ndarray) -> list[tuple[int, float, float, float, float]]:
        """Tracks (id, left, top, width, height) visible in this frame."""
        mask = self.foreground(frame_bgr)
        _, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        keep = stats[1:, cv2.CC_STAT_AREA] >= self.min_pixels
        return self.tracker.update(stats[1:][keep, :4].astype(np.float64))
