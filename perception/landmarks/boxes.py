"""Box poses from markers: one per marker, averaged per image and over the last n images."""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from dataclasses import dataclass

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, ground_pose, invert, same_pose, wrap
from percept.perception.landmarks.detection.detector import Marker, MarkerDetector
from percept.perception.landmarks.follow import MarkerSearch
from percept.perception.landmarks.geometry import (
    circular_mean,
    marker_in_box,
    marker_object_points,
)
from percept.perception.landmarks.pose import (
    MarkerPose,
    candidate_poses,
    fit_box_on_ground,
    marker_in_ground,
    placed,
    project_ground,
    refine,
    upright_and_facing,
)
from percept.perception.landmarks.records import BoxPose, average, box_error
from percept.perception.landmarks.settings import BoxSettings, LandmarkSettings, MarkerSettings

log = logging.getLogger("percept.landmarks")

SAME_HEADING = math.radians(10)  # two sightings of one marker id more apart: not one box
# Markers whose corners all moved less than this (pixels) since the last fit, seen from the
# same camera pose, give the box poses of that fit again (:meth:`BoxEstimator.observe`). The
# corners of a still box move 0.02-0.13 px from search to search (measured at 640x480); a
# quarter pixel is under a millimetre on the ground at a metre, and a box fit costs about a
# millisecond. A box that creeps is fitted again once it has moved this far from its last fit.
SAME_CORNERS = 0.25
# Seen from another camera pose (the head turned), the markers give the box poses of the last
# fit again when every corner is within this many pixels of where that fit's boxes, unmoved on
# the ground, put it: the last fit's corners moved as its boxes' image moved between the two
# camera poses. Measured on a recorded head pan at 640x480 (still boxes, the joints rounded to
# the servos' ticks): the corners of consecutive searches (3 frames apart) disagree with that by
# 0.6 px in the median and 1.15 px at the 90th percentile (the corner detection's own noise on
# a moving image), in the daemon, whose joint readings are later than the frames by a varying
# delay, by 1.8 px in the median. With 2 px, 269 of 300 searches kept the fit, and the poses
# kept differ from fitting every search by at most 2.4 mm and 0.55 degrees (99th percentile 1.9
# mm, 0.5 degrees), where fitting every search moves a still box's pose from one search to the
# next by up to 1.9 mm and 1.0 degree (bench/box_reuse.py --ticks). A box moved by 5 mm across
# the line of sight at 0.7 m (4 px), 1 cm along it or turned by 3 degrees is fitted again.
SAME_VIEW = 2.0


@dataclass(frozen=True)
class _Observation:
    """What one image's markers gave: the sightings on known boxes, each box's pose from them
    (None: its fit was dropped), and the ids seen more than once but not as one box.

    ``corners`` (4n, 2) are the markers' corners in order; ``ground`` (4n, 3) the same corners on
    the ground as the fitted box poses place them and ``seen`` (4n, 2) where those project from
    ``camera_pose`` (both None when a marker has no fitted box pose: then another camera pose's
    markers cannot be checked against this fit)."""

    markers: tuple[Marker, ...]
    camera_pose: CameraPose
    sightings: list[MarkerSighting]
    poses: dict[int, BoxPose | None]
    ambiguous: tuple[int, ...]
    corners: np.ndarray
    ground: np.ndarray | None
    seen: np.ndarray | None

    def holds_for(
        self, markers: list[Marker], camera_pose: CameraPose, camera: CameraModel
    ) -> bool:
        """Whether ``markers`` seen from ``camera_pose`` give this observation again: the same
        ids in the same order, and from the same camera pose every corner within
        :data:`SAME_CORNERS` of this one's; from another, within :data:`SAME_VIEW` of where
        this fit's boxes, unmoved, put it."""
        if len(markers) != len(self.markers) or any(
            a.id != b.id for a, b in zip(markers, self.markers, strict=True)
        ):
            return False
        if not markers:
            return True
        corners = _corners(markers)
        if same_pose(self.camera_pose, camera_pose):
            return bool(np.abs(corners - self.corners).max() <= SAME_CORNERS)
        if self.ground is None or self.seen is None:
            return False
        moved = self.corners + project_ground(self.ground, camera, camera_pose) - self.seen
        return bool(np.abs(corners - moved).max() <= SAME_VIEW)


def _corners(markers: list[Marker] | tuple[Marker, ...]) -> np.ndarray:
    """The markers' corners (4n, 2), in order."""
    if not markers:
        return np.zeros((0, 2))
    return np.concatenate([m.corners for m in markers]).astype(float, copy=False)


@dataclass(frozen=True)
class MarkerSighting:
    """One marker of a known box in one image: its chosen pose and the box pose it implies."""

    marker: Marker
    pose: MarkerPose
    box: BoxPose


class BoxEstimator:
    """Turns images (or detected markers) and camera poses into box poses in the ground frame.

    Thread-safe: the perception loop feeds it, the 5 Hz box publisher reads :meth:`boxes`.
    """

    def __init__(
        self,
        settings: LandmarkSettings,
        camera: CameraModel,
        detector: MarkerDetector | None = None,
    ) -> None:
        self.settings = settings
        self.camera = camera
        self.detector = detector or MarkerDetector.from_settings(settings)
        # Per marker id: its box, its settings, box <- marker and its corners in the box frame.
        self._markers: dict[int, tuple[BoxSettings, MarkerSettings, np.ndarray, np.ndarray]] = {}
        for box in settings.boxes:
            for m in box.markers:
                T = marker_in_box(box, m)
                corners = marker_object_points(m.side) @ T[:3, :3].T + T[:3, 3]
                self._markers[m.id] = (box, m, invert(T), corners)
        # The marker search: full, or following the markers found before (``follow``); the
        # daemon calls it on its marker thread, in the order it takes frames.
        sides = {m.id: m.side for box in settings.boxes for m in box.markers}
        self.search = MarkerSearch(self.detector, camera, sides, settings.follow)
        self._history: dict[int, deque[tuple[float, BoxPose]]] = {}
        # Per box: how many poses its history has had, and its average over which of them
        # (their positions in the history), for boxes() between changes.
        self._added: dict[int, int] = {}
        self._averaged: dict[int, tuple[tuple[int, tuple[int, ...]], BoxPose]] = {}
        self._last: _Observation | None = None
        self.refits_saved = 0
        """How many searches gave the box poses of the search before (no fit), for profiles."""
        self._frames = 0
        self._lock = threading.Lock()
        self.ambiguities = 0  # images x marker ids seen more than once, not as one box
        self.ambiguous_ids: tuple[int, ...] = ()  # the last few of those ids

    def process(self, image: np.ndarray, camera_pose: CameraPose, now: float) -> bool:
        """Feed one frame taken at monotonic time ``now``; markers are looked for on every
        ``every``-th frame only. Returns whether this frame was searched."""
        self._frames += 1
        if (self._frames - 1) % self.settings.every:
            return False
        self.observe(self.search(image, camera_pose), camera_pose, now)
        return True

    def observe(
        self, markers: list[Marker], camera_pose: CameraPose, now: float
    ) -> list[MarkerSighting]:
        """Add one image's detected markers; returns the sightings of markers on known boxes.

        A marker id seen more than once is used when every sighting of it gives the same box
        pose (within ``same_box``; the box fit then averages them); otherwise none of them is,
        and the id is counted in :attr:`ambiguities` and :attr:`ambiguous_ids`. Markers that
        give the last fit again (:meth:`_Observation.holds_for`: the boxes did not move) add
        its box poses without a fit, and the sightings returned are that fit's."""
        known = [m for m in markers if m.id in self._markers]  # no others take part
        last = self._last
        if last is not None and last.holds_for(known, camera_pose, self.camera):
            self.refits_saved += 1
            seen = last
        else:
            seen = self._last = self._observation(known, camera_pose)
        for marker_id in seen.ambiguous:
            log.debug("marker %d seen more than once, not as one box: not used", marker_id)
            self.ambiguities += 1
            self.ambiguous_ids = (*self.ambiguous_ids[-7:], marker_id)
        with self._lock:
            for box_id, pose in seen.poses.items():
                if pose is not None:
                    history = self._history.setdefault(box_id, deque(maxlen=self.settings.window))
                    history.append((now, pose))
                    self._added[box_id] = self._added.get(box_id, 0) + 1
        return seen.sightings

    def _observation(self, markers: list[Marker], camera_pose: CameraPose) -> _Observation:
        """The sightings and box poses of one image's ``markers`` (all of known ids)."""
        each = [self._sighting(m, camera_pose) for m in markers]
        by_id: dict[int, list[MarkerSighting | None]] = {}
        for m, sighting in zip(markers, each, strict=True):
            by_id.setdefault(m.id, []).append(sighting)
        sightings: list[MarkerSighting] = []
        ambiguous: list[int] = []
        for marker_id, seen in by_id.items():
            if len(seen) > 1 and not self._one_box(seen):
                ambiguous.append(marker_id)
                continue
            sightings.extend(s for s in seen if s is not None)
        per_box: dict[int, list[MarkerSighting]] = {}
        for s in sightings:
            per_box.setdefault(s.box.id, []).append(s)
        poses = {box_id: self._combine(group, camera_pose) for box_id, group in per_box.items()}
        ground = self._on_ground(markers, each, poses, ambiguous)
        seen_at = None if ground is None else project_ground(ground, self.camera, camera_pose)
        return _Observation(
            tuple(markers),
            camera_pose,
            sightings,
            poses,
            tuple(ambiguous),
            _corners(markers),
            ground,
            seen_at,
        )

    def _on_ground(
        self,
        markers: list[Marker],
        each: list[MarkerSighting | None],
        poses: dict[int, BoxPose | None],
        ambiguous: list[int],
    ) -> np.ndarray | None:
        """The corners (4n, 3) of ``markers`` on the ground, each marker on its box at the box
        pose fitted; None when one of them has none (its sighting or its box's fit dropped, or
        its id seen more than once)."""
        if not markers:
            return None
        ground = []
        for m, sighting in zip(markers, each, strict=True):
            pose = None if sighting is None else poses.get(sighting.box.id)
            if pose is None or m.id in ambiguous:
                return None
            ground.append(placed(self._markers[m.id][3], (pose.x, pose.y, pose.theta)))
        return np.concatenate(ground)

    def _one_box(self, seen: list[MarkerSighting | None]) -> bool:
        """Whether sightings of one id all give one pose of its box."""
        boxes = [s.box for s in seen if s is not None]
        if len(boxes) < len(seen):  # one of them fits no marker on a box face
            return False
        errors = (box_error(b, boxes[0].x, boxes[0].y, boxes[0].theta) for b in boxes[1:])
        return all(p <= self.settings.same_box and h <= SAME_HEADING for p, h in errors)

    def _combine(self, seen: list[MarkerSighting], camera_pose: CameraPose) -> BoxPose | None:
        """One box pose from the sightings of one box's markers in one image."""
        mean = average([s.box for s in seen])
        if self.settings.box_fit == "average":
            return mean
        points = np.concatenate([self._markers[s.marker.id][3] for s in seen])
        corners = np.concatenate([s.marker.corners for s in seen])
        (x, y, theta), rms = fit_box_on_ground(
            corners, points, self.camera, camera_pose, (mean.x, mean.y, mean.theta)
        )
        if rms > self.settings.max_reprojection:
            log.debug("box %d: ground fit reprojects at %.2f px, dropped", mean.id, rms)
            return None
        return BoxPose(mean.id, x, y, theta, len(seen))

    def boxes(self, now: float) -> list[BoxPose]:
        """Every box seen within ``forget_after`` seconds of ``now``, averaged over its last
        ``window`` images, sorted by id."""
        out = []
        with self._lock:
            for box_id in sorted(self._history):
                history = self._history[box_id]
                recent = tuple(
                    k for k, (t, _) in enumerate(history) if now - t <= self.settings.forget_after
                )
                if not recent:
                    continue
                # The same poses as at the last call: the same average (the daemon asks for
                # it twice a frame and the publisher five times a second).
                key = (self._added[box_id], recent)
                kept = self._averaged.get(box_id)
                if kept is None or kept[0] != key:
                    kept = self._averaged[box_id] = (key, average([history[k][1] for k in recent]))
                out.append(kept[1])
        return out

    def _previous_theta(self, box_id: int) -> float | None:
        with self._lock:
            history = self._history.get(box_id)
            if not history:
                return None
            return circular_mean([p.theta for _, p in history])

    def _sighting(self, marker: Marker, camera_pose: CameraPose) -> MarkerSighting | None:
        known = self._markers.get(marker.id)
        if known is None:
            return None
        box, spec, marker_to_box, _ = known
        options = []
        for pose in candidate_poses(marker.corners, spec.side, self.camera):
            T = marker_in_ground(pose, camera_pose)
            if upright_and_facing(T, camera_pose, self.settings.max_tilt):
                options.append((pose, ground_pose(T @ marker_to_box)[2]))
        if not options:
            log.debug("marker %d: no pose fits a marker on a vertical face", marker.id)
            return None
        previous = self._previous_theta(box.id)
        if previous is not None and len(options) > 1:
            options.sort(key=lambda o: abs(wrap(o[1] - previous)))
        pose = refine(options[0][0], marker.corners, spec.side, self.camera, self.settings.refine)
        if pose.error > self.settings.max_reprojection:
            log.debug("marker %d: reprojection error %.2f px, dropped", marker.id, pose.error)
            return None
        x, y, theta = ground_pose(marker_in_ground(pose, camera_pose) @ marker_to_box)
        return MarkerSighting(marker, pose, BoxPose(box.id, x, y, theta, 1))
