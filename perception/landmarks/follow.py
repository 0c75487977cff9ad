"""Following known markers between full searches, in small windows predicted from the camera's
motion.

A full marker search reads the whole image; once markers are found, the next images need only
be searched where those markers will be. A marker of known side has a pose (IPPE_SQUARE on its
corners), so its corners in the next image follow from the two camera poses (forward
kinematics gives one per frame): the window around them is searched with the same detector,
windows that overlap as one.
Windows start on the detector's pixel grid, so a marker found in its window has the corners a
full search gives. Markers that newly come into view wait for the next full search, every
``follow + 1``-th search.

:class:`MarkerSearch` holds what the last search found; it is a deterministic function of the
images and camera poses it is given, in order, so a replay that gives it the same ones gets the
same markers.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from percept.kinematics.camera import CameraModel, cv_from_ground, cv_to_camera
from percept.kinematics.pose import CameraPose, invert
from percept.perception.landmarks.detection.detector import Marker, MarkerDetector, reading_order
from percept.perception.landmarks.geometry import marker_object_points
from percept.perception.landmarks.pose import candidate_poses


def predict_corners(
    corners: np.ndarray, side: float, camera: CameraModel, seen: CameraPose, now: CameraPose
) -> np.ndarray:
    """Where the corners (4, 2) of a marker of ``side`` metres, seen from the camera at pose
    ``seen``, are in the image of the camera at pose ``now``."""
    if np.array_equal(seen.R, now.R) and np.array_equal(seen.t, now.t):
        return corners  # where they were (a still head: no pose to fit, 0.3 ms a marker)
    pose = candidate_poses(corners, side, camera)[0]  # both candidates share the corners
    in_cv = marker_object_points(side) @ pose.matrix()[:3, :3].T + pose.tvec
    T = cv_from_ground(now) @ invert(cv_from_ground(seen))
    return camera.project(cv_to_camera(in_cv @ T[:3, :3].T + T[:3, 3]))


def window(corners: np.ndarray, width: int, height: int) -> tuple[int, int, int, int] | None:
    """The pixels of a ``width`` x ``height`` image to search for a marker expected at
    ``corners``: its box and half its size around it (AprilTag's quads need the marker's
    surroundings); None if out of the image."""
    if not np.all(np.isfinite(corners)):
        return None
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    margin = 0.5 * float((hi - lo).max()) + 8
    x0, y0 = (max(int(v - margin), 0) for v in lo)
    x1, y1 = min(int(hi[0] + margin) + 1, width), min(int(hi[1] + margin) + 1, height)
    return (x0, y0, x1, y1) if x1 - x0 >= 8 and y1 - y0 >= 8 else None


class MarkerSearch:
    """Full searches every ``follow + 1``-th call, and in between only the markers of known
    ``sides`` (metres, by id) that the last search found, each in its predicted window."""

    def __init__(
        self,
        detector: MarkerDetector,
        camera: CameraModel,
        sides: Mapping[int, float],
        follow: int,
    ) -> None:
        self.detector = detector
        self.camera = camera
        self.sides = dict(sides)
        self.follow = follow
        self.full_searches = 0
        self.followed = 0
        self._since_full = follow  # the first search is full
        self._last: list[Marker] = []
        self._last_pose: CameraPose | None = None

    def __call__(self, image: np.ndarray, camera_pose: CameraPose | None) -> list[Marker]:
        """The markers in ``image``, taken by a camera at ``camera_pose`` (None: unknown, which
        makes the search full)."""
        gray = self.detector.prepare(image)
        if self._since_full < self.follow and camera_pose is not None and self._last:
            markers = self._follow(gray, camera_pose)
            self._since_full += 1
            self.followed += 1
        else:
            markers = self.detector.detect_prepared(gray)
            self._since_full = 0
            self.full_searches += 1
        self._last = [m for m in markers if m.id in self.sides] if camera_pose else []
        self._last_pose = camera_pose
        return markers

    def _follow(self, gray: np.ndarray, camera_pose: CameraPose) -> list[Marker]:
        assert self._last_pose is not None
        expected: list[tuple[Marker, np.ndarray, tuple[int, int, int, int]]] = []
        for last in self._last:
            corners = predict_corners(
                last.corners, self.sides[last.id], self.camera, self._last_pose, camera_pose
            )
            box = window(corners, gray.shape[1], gray.shape[0])
            if box is not None:
                expected.append((last, corners, box))
        found: list[Marker] = []
        # Windows that overlap are searched as one (a box's markers on two faces side by side):
        # each search costs about as much again for its own set-up as for its pixels.
        for box, members in merge_windows([e[2] for e in expected]):
            markers = self.detector.detect_prepared(gray, box)
            for last, corners, _box in (expected[i] for i in members):
                centre = corners.mean(axis=0)
                near = 0.5 * float(np.ptp(corners, axis=0).max()) + 4
                options = [
                    m
                    for m in markers
                    if m.id == last.id
                    and np.linalg.norm(m.corners.mean(axis=0) - centre) < near
                    and not any(_same(m, f) for f in found)
                ]
                if options:
                    found.append(
                        min(options, key=lambda m: np.linalg.norm(m.corners.mean(0) - centre))
                    )
        return sorted(found, key=reading_order)


def merge_windows(
    boxes: list[tuple[int, int, int, int]],
) -> list[tuple[tuple[int, int, int, int], list[int]]]:
    """``boxes`` ``(x0, y0, x1, y1)`` with those that overlap replaced by the box around them,
    again until none overlap: each merged box with the indices of the boxes it covers."""
    merged = [(box, [i]) for i, box in enumerate(boxes)]
    joined = True
    while joined:
        joined = False
        for i in range(len(merged)):
            for j in range(i + 1, len(merged)):
                (a, into), (b, more) = merged[i], merged[j]
                if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
                    box = (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
                    merged[i] = (box, into + more)
                    del merged[j]
                    joined = True
                    break
            if joined:
                break
    return merged


def _same(a: Marker, b: Marker) -> bool:
    return a.id == b.id and bool(np.abs(a.corners - b.corners).max() < 1.0)
