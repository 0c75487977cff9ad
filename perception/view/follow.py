"""The mosaic brought into each frame's view, and the previous frame brought into the current one.

For a frame taken at a camera pose, the lattice points of the grid get their map coordinates
(:meth:`~percept.perception.view.map.directions.Lookup.coarse`), and one compiled loop
(:func:`~percept.perception.view.bounds_kernels.bounds_in_view`) interpolates them to every grid
pixel and gives it the bounds of the foreground and motion tests of its nearest cell, that cell's
brightness (what the alignment compares the frame with) and its index (what the learning adds
to): from there on a frame is classified exactly like one of a still camera (``cv2.inRange``).
While the pose stays the same the view's bounds are kept, so a head that holds still costs what
a still camera costs.

Joint encoders, timestamps and gears are not exact, so the pose only predicts the alignment:
:meth:`FollowingBackground.view` finds the shift between the model's brightness in the
predicted view and the frame's (phase correlation), turns it into a pan and tilt of the pose,
and keeps that correction for the next frames (an encoder's offset stays; a delay changes with
the head's speed) as long as it is within ``max_shift`` degrees. Once a refinement finds the
frame where the correction put it, the next :data:`REFINE_EVERY` - 1 frames take the
correction as it is, unless the head's speed changes. A pose 1 degree off or 20 ms late comes
out within half a grid pixel of the true pose's alignment (README, "Moving head").

Motion (SPEC §4.3) compares a frame with the previous one brought into its view through the
homography of the two poses (:func:`percept.kinematics.ground.view_homography`, exact for the
floor and for a pure rotation; :mod:`percept.perception.tracking.motion`); pixels the previous
frame did not see keep the current frame's values, so they count as not moved.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.ground import view_homography
from percept.kinematics.pose import CameraPose, rpy_matrix, same_pose
from percept.perception.params import ViewParams
from percept.perception.view.alignment_kernels import alignment_images
from percept.perception.view.bounds_kernels import bounds_in_view
from percept.perception.view.map.directions import Lattice, Lookup
from percept.perception.view.mosaic import ViewMosaic

ALIGN_WIDTH = 160
"""Frames wider than this are aligned on a copy shrunk to it (the shift is no worse than a
tenth of a pixel there, and the correlation four times cheaper at 320 wide)."""
MIN_RESPONSE = 0.05
"""Phase correlation peaks below this are no alignment (a blank view)."""
MIN_KNOWN = 0.25
"""A view with less of the known background than this is not aligned."""
SAME_VIEW = 0.1
"""Grid pixels: two poses whose views differ by less than this at the image corners see the same
pixels (the head held still; an encoder's last digit)."""
SMALL_SHIFT = 0.5
"""Grid pixels: a frame found shifted by less than this against the prediction keeps the
prediction (the spread of the bounds absorbs it; the correction serves from the next frame on),
which saves a second lookup in most frames."""
REFINE_EVERY = 3
"""Frames: after a refinement that found less than :data:`SMALL_SHIFT`, the alignment is refined
again on the third frame at the latest, and on the next one if the view's motion per frame
changed by :data:`SMALL_SHIFT` since (the correction serves in between: an encoder's offset
stays, and the error of a delay is the head's speed times the delay, which changes only when the
speed does); after a larger shift, on the next frame."""


@dataclass(frozen=True)
class FrameView:
    """The background of one view: per grid pixel its nearest cell and test bounds."""

    coarse: np.ndarray
    """(rows, cols, 2) float32 map coordinates (column, row) of the lattice points of
    ``lattice``, from which those of every grid pixel are interpolated."""
    lattice: Lattice
    nearest: np.ndarray
    """(H, W) int32 flat index of each grid pixel's nearest cell of the map (-1: outside)."""
    lower: np.ndarray
    upper: np.ndarray
    """(H, W, 3) uint8 foreground bounds: background when lower <= value <= upper."""
    moved: np.ndarray
    """(H, W, 3) uint8: moved when the difference to the previous frame is above this."""
    brightness: np.ndarray
    """(H, W) uint8 the mean Y of each pixel's nearest cell, 0 where it is unknown or outside
    the map: what the frame is aligned with."""
    known: np.ndarray
    """(H, W) bool: the map knows the background there."""

    @cached_property
    def cells(self) -> np.ndarray:
        """(H, W, 2) float32 map coordinates (column, row) of each grid pixel."""
        return self.lattice.interpolate(self.coarse)

    @property
    def unknown_fraction(self) -> float:
        return float(1.0 - np.count_nonzero(self.known) / self.known.size)

    def classify(self, ycc: np.ndarray) -> np.ndarray:
        """Foreground of the grid's YCrCb values as a 0/1 uint8 mask (before noise reduction)."""
        background = cv2.inRange(ycc, self.lower, self.upper)
        return cv2.threshold(background, 0, 1, cv2.THRESH_BINARY_INV)[1]


class FollowingBackground:
    """The :class:`ViewMosaic` seen from each frame's camera pose."""

    def __init__(
        self,
        mosaic: ViewMosaic,
        camera: CameraModel,
        step: int,
        grid: tuple[int, int],
        params: ViewParams,
        lag: float = 0.0,
    ) -> None:
        self.mosaic, self.params = mosaic, params
        self.lag = lag
        """Frames the poses lag behind the images (the calibration's
        :func:`~percept.perception.view.register.pose_lag`)."""
        self.lookup = Lookup(camera, step, grid)
        self.K = grid_camera_matrix(camera, step)
        self.grid = grid
        self.max_turn = math.radians(params.max_shift)
        self.correction = (0.0, 0.0)
        """Pan and tilt (radians) the poses were found off by, beyond their lag, as of the last
        refinement."""
        self.timed: CameraPose | None = None
        """The pose of the last view turned by the lag: where the joints were when the image
        was taken (without the correction, whose steps from one refinement to the next would
        shake the previous frame's warp and the anchors' prediction)."""
        self._key: tuple[bytes, bytes, int] | None = None
        self._view: FrameView | None = None
        self.correlator = Correlator()
        self._unrefined = 0
        """Frames that may still take the correction without a refinement."""
        self._aim: np.ndarray | None = None
        """Pan and tilt of the optical axis of the previous frame's pose (radians)."""
        self._speed_refined: np.ndarray | None = None
        """The view's motion per frame (pan, tilt, radians) at the last refinement."""

    def view(self, pose: CameraPose, y: np.ndarray) -> FrameView:
        """The background of the view from ``pose``; ``y`` (H, W) uint8 the frame's grid
        brightness, which the alignment is refined against."""
        key = (pose.R.tobytes(), pose.t.tobytes(), self.mosaic.version)
        if key == self._key and self._view is not None:
            return self._view
        self._key = key
        directions = self.mosaic.directions
        if not self.params.refine:
            self.timed = pose
            self._view = self._view_of(self.lookup.coarse(directions, pose))
            return self._view
        aim = np.array(aim_of(pose))
        speed = None if self._aim is None else aim - self._aim
        self._aim = aim
        # Start from the correction found for the previous frames: an encoder's offset stays,
        # and the poses' lag turns the view by the head's motion per frame times that lag.
        lead = (0.0, 0.0) if speed is None else (self.lag * speed[0], self.lag * speed[1])
        self.timed = turned(pose, *lead)
        predicted = turned(self.timed, *self.correction)
        view = self._view_of(self.lookup.coarse(directions, predicted))
        if self._unrefined > 0 and self._steady(speed):
            self._unrefined -= 1
            self._view = view
            return view
        self._speed_refined = speed
        shift = self._shift(view, y)
        large = math.hypot(*shift) >= SMALL_SHIFT
        self._unrefined = 0 if large else REFINE_EVERY - 1
        if shift != (0.0, 0.0):
            pan, tilt = turn_of(predicted, shift, self.K)
            pan, tilt = self.correction[0] + pan, self.correction[1] + tilt
            if math.hypot(pan, tilt) <= self.max_turn:
                self.correction = (pan, tilt)
                if large:
                    coarse = self.lookup.coarse(directions, turned(self.timed, pan, tilt))
                    view = self._view_of(coarse)
        self._view = view
        return view

    def _steady(self, speed: np.ndarray | None) -> bool:
        """The view moves per frame as it did at the last refinement, to within
        :data:`SMALL_SHIFT` grid pixels."""
        if speed is None or self._speed_refined is None:
            return False
        change = np.abs(speed - self._speed_refined) * (self.K[0, 0], self.K[1, 1])
        return bool(math.hypot(*change) < SMALL_SHIFT)

    def _view_of(self, coarse: np.ndarray) -> FrameView:
        """The view whose lattice points have map coordinates ``coarse``."""
        shape = self.grid
        lower, upper, moved = (np.empty((*shape, 3), np.uint8) for _ in range(3))
        brightness = np.empty(shape, np.uint8)
        nearest = np.empty(shape, np.int32)
        m, lattice = self.mosaic, self.lookup.lattice
        bounds_in_view(
            coarse, lattice.columns, lattice.column_weights, lattice.rows, lattice.row_weights,
            m.words, *m.directions.shape, lower, upper, moved, brightness, nearest,
        )  # fmt: skip
        return FrameView(
            coarse=coarse,
            lattice=lattice,
            nearest=nearest,
            lower=lower,
            upper=upper,
            moved=moved,
            brightness=brightness,
            known=brightness > 0,
        )

    def _shift(self, view: FrameView, y: np.ndarray) -> tuple[float, float]:
        """How far (grid pixels) the frame's brightness ``y`` lies moved against the mosaic's
        brightness in ``view`` (:meth:`Correlator.shift`)."""
        return self.correlator.shift(view.brightness, y)


class Correlator:
    """The shift between a model's brightness and a frame's, by phase correlation (the window
    of the last image size kept)."""

    def __init__(self) -> None:
        self._window: np.ndarray | None = None

    def shift(self, model: np.ndarray, y: np.ndarray) -> tuple[float, float]:
        """How far (pixels) the brightness ``y`` (H, W) uint8 lies moved against ``model``
        (H, W) uint8, 0 where the model does not know the background; (0, 0) when the
        correlation is too weak or the model knows too little of the view."""
        # Outside the known background both images hold their own mean: no structure there.
        count, a, b = alignment_images(model, y)
        if count < MIN_KNOWN * model.size:
            return 0.0, 0.0
        fx = fy = 1.0
        if a.shape[1] > ALIGN_WIDTH:
            # A height the DFT takes fast (a product of 2, 3 and 5), each axis its own scale.
            fx = a.shape[1] / ALIGN_WIDTH
            rows = cv2.getOptimalDFTSize(round(a.shape[0] / fx))
            fy = a.shape[0] / rows
            a = cv2.resize(a, (ALIGN_WIDTH, rows), interpolation=cv2.INTER_AREA)
            b = cv2.resize(b, (ALIGN_WIDTH, rows), interpolation=cv2.INTER_AREA)
        if self._window is None or self._window.shape != a.shape:
            self._window = cv2.createHanningWindow((a.shape[1], a.shape[0]), cv2.CV_32F)
        (dx, dy), response = cv2.phaseCorrelate(a, b, self._window)
        if response < MIN_RESPONSE:
            return 0.0, 0.0
        return float(dx * fx), float(dy * fy)


def turn_of(pose: CameraPose, shift: tuple[float, float], K: np.ndarray) -> tuple[float, float]:
    """Pan and tilt (radians) that move the image of a camera at ``pose`` by ``shift``
    (pixels of camera matrix ``K``) at its centre: about the ground's vertical and about the
    camera's horizontal axis, the joints whose encoders and timing the error comes from."""
    dx, dy = shift
    # What the centre pixel of the image now shows is what the pose's pixel (c - shift) shows.
    target = _azimuth_elevation(pose.R @ np.array([1.0, dx / K[0, 0], dy / K[1, 1]]))
    axis = aim_of(pose)
    return target[0] - axis[0], target[1] - axis[1]


def aim_of(pose: CameraPose) -> tuple[float, float]:
    """Azimuth and elevation (radians, ground frame) of the optical axis of a camera at
    ``pose``."""
    return _azimuth_elevation(pose.R[:, 0])


def _azimuth_elevation(v: np.ndarray) -> tuple[float, float]:
    return math.atan2(v[1], v[0]), math.atan2(v[2], math.hypot(v[0], v[1]))


def turned(pose: CameraPose, pan: float, tilt: float) -> CameraPose:
    """``pose`` turned by ``pan`` about the ground's vertical and ``tilt`` (up) about the
    camera's horizontal axis. The centre stays put: a degree turns it a fraction of a
    millimetre around the pan axis."""
    if pan == 0.0 and tilt == 0.0:
        return pose
    # Ry(-tilt) in the camera frame raises the optical axis; Rz(pan) in the ground frame turns
    # it about the vertical.
    R = rpy_matrix((0.0, 0.0, pan)) @ pose.R @ rpy_matrix((0.0, -tilt, 0.0))
    return CameraPose(R=R, t=pose.t)


def same_view(K: np.ndarray, size: tuple[float, float], a: CameraPose, b: CameraPose) -> bool:
    """Cameras with (grid) camera matrix ``K`` and image ``size`` (width, height) at poses
    ``a`` and ``b`` see the same pixels: their views differ by less than :data:`SAME_VIEW` at
    the image's corners."""
    return same_pose(a, b) or moves_little(view_homography(K, a, b), size)


def moves_little(H: np.ndarray, size: tuple[float, float]) -> bool:
    """The homography ``H`` moves the corners of an image of ``size`` (width, height) by less
    than :data:`SAME_VIEW` pixels."""
    w, h = size
    corners = np.array([[0, 0, 1], [w, 0, 1], [0, h, 1], [w, h, 1]], float)
    moved = corners @ H.T
    with np.errstate(divide="ignore", invalid="ignore"):
        off = moved[:, :2] / moved[:, 2:] - corners[:, :2]
    return bool(np.all(np.abs(off) < SAME_VIEW))


def grid_camera_matrix(camera: CameraModel, step: int) -> np.ndarray:
    """The camera matrix of the grid of every ``step``-th pixel (grid pixel j is pixel j s)."""
    return np.diag([1.0 / step, 1.0 / step, 1.0]) @ camera.K


def on_grid(H: np.ndarray, step: int) -> np.ndarray:
    """The homography ``H`` between two views' pixels as one between the pixels of their grids
    of every ``step``-th pixel (grid pixel j is pixel j s)."""
    scale = np.array([1.0 / step, 1.0 / step, 1.0])
    return H * scale[:, None] / scale[None, :]
