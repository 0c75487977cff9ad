"""One frame's way through the perception core (SPEC §4.1-4.4)::

    BGR -> YCrCb -> foreground + motion -> regions -> colour split -> percepts -> anchors

:class:`Perception` holds the state that lives across frames (background model, previous frame,
anchors); :meth:`Perception.process` takes one frame and its time and returns a
:class:`FrameResult`. A frame is a full-size BGR image, or a
:class:`~percept.perception.segmentation.grid_frame.GridFrame` already on perception's grid (the
background is then calibrated on grid frames too). A frame that is not of the calibrated size and
kind is skipped with a logged error, never raised: one bad frame from a camera must not stop a
robot.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from percept.kinematics.camera import CameraModel, grid_shape
from percept.kinematics.ground import view_homography
from percept.kinematics.pose import CameraPose
from percept.perception.backgrounds import Background, background_of
from percept.perception.colour import Coding, to_ycrcb
from percept.perception.light.adaptation import LightAdaptation, LightStatus
from percept.perception.params import PerceptionParams
from percept.perception.segmentation.background import (
    BackgroundModel,
    CalibrationError,
    Progress,
    describe,
)
from percept.perception.segmentation.grid_frame import GridFrame, PerceptionFrame, grid_ycrcb
from percept.perception.segmentation.labelling.regions import Regions, grid_step
from percept.perception.segmentation.percepts import Percept, PerceptSet, empty
from percept.perception.segmentation.segment import Segmentation, Segmenter
from percept.perception.tracking.anchors import Anchor, AnchorTracker
from percept.perception.tracking.motion import Motion, MotionDetector, open_mask, opening_kernel
from percept.perception.view import calibration as view
from percept.perception.view.calibration import ViewCalibration, calibrate_view
from percept.perception.view.follow import (
    FollowingBackground,
    grid_camera_matrix,
    moves_little,
    on_grid,
    same_pose,
)

log = logging.getLogger("percept.perception")

STALE_HOLD = 1.0
"""Seconds: for at most this long in a row, frames whose camera pose is not fresh (joint
readings late, a joint of the camera's chain not answering) leave the anchors as they stand. The
head may have turned since the readings, so the background is brought into the wrong view: its
foreground and motion would make anchors on the floor, and carry the anchors' boxes and ground
positions off their objects. Longer than that, a joint has stopped answering (gaze stops the
head then) and the frames are taken as they come."""


class NotCalibrated(RuntimeError):
    """``process`` was called before a background was calibrated or loaded."""


@dataclass(frozen=True)
class Masks:
    """The per-pixel results of one frame; the images are built when first read."""

    shape: tuple[int, int]
    fg: np.ndarray = field(repr=False)
    """0/1 foreground after noise reduction, of the grid the frame was worked on
    (``regions.step``; (H, W) when every pixel was)."""
    moved: Motion = field(repr=False)
    regions: Regions = field(repr=False)
    pixel_classes: np.ndarray = field(repr=False)
    """Class of each of ``regions.pixels``: 0 no model, j + 1 model j of ``class_ids``."""
    class_ids: tuple[str, ...] = ()
    """Anchor id of each model that took part in the colour split, in class order."""

    @property
    def foreground(self) -> np.ndarray:
        """(H, W) uint8, 255 where foreground."""
        return _upsample(self.fg, self.regions.step, self.shape) * np.uint8(255)

    @property
    def motion(self) -> np.ndarray:
        """(H, W) uint8, 255 where something moved since the previous frame."""
        return _upsample(self.moved.mask(), self.moved.step, self.shape) * np.uint8(255)

    @property
    def classes(self) -> np.ndarray:
        """(H, W) int16: -1 background, 0 foreground of no model, j + 1 model ``class_ids[j]``.

        Pixels of regions too small to keep count as background. On a grid (``regions.step``
        > 1) every pixel takes the class of the grid pixel at or above and left of it.
        """
        grid = self.regions.labels.shape
        out = np.full(grid[0] * grid[1], -1, np.int16)
        out[self.regions.pixels] = self.pixel_classes
        return _upsample(out.reshape(grid), self.regions.step, self.shape)


def _upsample(grid: np.ndarray, step: int, shape: tuple[int, int]) -> np.ndarray:
    """An image of ``shape`` in which every pixel has the value of the grid pixel at or above
    and left of it."""
    if step == 1:
        return grid
    return np.repeat(np.repeat(grid, step, axis=0), step, axis=1)[: shape[0], : shape[1]]


@dataclass(frozen=True)
class FrameResult:
    """What one frame gave: its percepts, the anchors after it, and the masks."""

    percept_set: PerceptSet = field(repr=False)
    anchors: list[Anchor]
    masks: Masks | None
    """None when the frame was skipped."""
    t: float
    skipped: bool = False
    """The frame was unusable; ``anchors`` are those of the previous frame."""
    light: LightStatus | None = None
    """The light as this frame saw it (None: light adaptation off, or the frame skipped)."""
    unknown_fraction: float = 0.0
    """Fraction of the frame whose background is not known yet (never foreground there)."""

    @cached_property
    def percepts(self) -> list[Percept]:
        """The percepts one by one (built on first use)."""
        return self.percept_set.to_list()


class Perception:
    """Background, foreground, motion, regions, splitting and anchors for one camera."""

    def __init__(
        self,
        params: PerceptionParams,
        width: int,
        height: int,
        camera: CameraModel | None = None,
    ) -> None:
        self.params = params
        self.camera = camera
        """The camera's intrinsics, for following a moving head (None: a still camera)."""
        self.width, self.height = width, height
        area = width * height
        self.min_region_pixels = round(params.regions.min_area * area)
        self.min_split_pixels = round(params.split.min_area * area)
        self.step = grid_step(width, height, params.regions.grid_pixels)
        self.kernel = opening_kernel(params.regions.opening)
        self.background: BackgroundModel | None = None
        self.grid_background: BackgroundModel | None = None
        """:attr:`background` on the grid the frames are worked on."""
        self.grid_frames = False
        """The background was calibrated on grid frames (:class:`GridFrame`), and takes only
        those; else only full-size BGR frames (at grid step 1 both are the same)."""
        self.motion: MotionDetector | None = None
        self.light: LightAdaptation | None = None
        """Keeps the background valid through the light of a session (None: switched off)."""
        self.coding = Coding.of(params.regions.colour_model, params.regions.bins)
        """How pixels are counted into the colour models of regions, percepts and anchors."""
        self.tracker = AnchorTracker(params.anchors, width, height, self.coding, camera)
        self.calibration: ViewCalibration | None = None
        """The calibration with camera poses (None: without)."""
        self.following: FollowingBackground | None = None
        """The background over viewing directions, when calibrated with camera poses."""
        self.subtraction: Background | None = None
        """What every frame's foreground is told from, chosen with the background (fixed,
        lit, or the moving head's view background around either)."""
        self._last: list[Anchor] = []
        self._pose: CameraPose | None = None
        """The pose of the previous frame (or of the calibration's last frame)."""
        self._stale_since: float | None = None
        """Time of the first of the frames in a row whose pose was not fresh."""
        self._grid_K = None if camera is None else grid_camera_matrix(camera, self.step)
        self.segmenter = Segmenter(
            self.coding,
            self.min_region_pixels,
            params.split,
            self.min_split_pixels,
            self.step,
        )

    # -- background ---------------------------------------------------------------------------

    def calibrate(
        self,
        frames: Iterable[PerceptionFrame],
        progress: Progress | None = None,
        poses: Iterable[CameraPose] | None = None,
    ) -> None:
        """Learn the background from the first ``background.calibration_frames`` frames (BGR
        images, or grid frames: then later frames must be grid frames too); ``poses`` are the
        camera poses of the frames, in the same order (None: a still camera). With poses the
        background is also learned over viewing directions, for frames taken at any pose (the
        camera model must be given)."""
        frames = self._sized(frames)
        if poses is None:
            self._use(BackgroundModel.calibrate(frames, self.params.background, progress))
            return
        if self.camera is None:
            raise CalibrationError("calibrating with camera poses needs the camera model")
        calibration = calibrate_view(frames, poses, self.camera, self.step, self.params, progress)
        self._use(calibration.model, calibration)
        self._pose = calibration.last

    def _sized(self, frames: Iterable[PerceptionFrame]) -> Iterator[PerceptionFrame]:
        """The calibration frames, each checked to be of this perception's size: a full frame,
        or a grid frame of its grid (the model's size then says which kind it takes)."""
        for n, frame in enumerate(frames, start=1):
            if isinstance(frame, GridFrame):
                if frame.step != self.step:
                    raise CalibrationError(
                        f"calibration frame {n}: a grid frame of step {frame.step}, "
                        f"expected step {self.step}"
                    )
                shape, expected = frame.ycc.shape, (*self._grid_shape, 3)
            else:
                shape, expected = frame.shape, (self.height, self.width, 3)
            if shape != expected:
                raise CalibrationError(f"calibration frame {n} is {shape}, expected {expected}")
            yield frame

    def load_background(self, path: str | Path) -> None:
        """Use a calibration saved by :meth:`save_background`."""
        model = BackgroundModel.load(path, self.params.background)
        self._use(model, view.load(path, model, self.params))

    def save_background(self, path: str | Path) -> None:
        """Write the calibration to an ``.npz`` file."""
        if self.background is None:
            raise NotCalibrated("no background to save")
        if self.calibration is None:
            self.background.save(path)
        else:
            view.save(path, self.calibration)

    def _use(self, model: BackgroundModel, calibration: ViewCalibration | None = None) -> None:
        grid = self._grid_shape
        if model.shape not in ((self.height, self.width), grid):
            raise CalibrationError(
                f"background is {model.shape[1]}x{model.shape[0]}, frames are "
                f"{self.width}x{self.height} (on the grid of step {self.step}: "
                f"{grid[1]}x{grid[0]})"
            )
        self.background = model
        self.grid_frames = model.shape != (self.height, self.width)
        self.grid_background = model if self.grid_frames else model.on_grid(self.step)
        self.motion = MotionDetector(
            self.grid_background, self.params.motion.k, self.params.regions.opening, self.step
        )
        light = self.params.light
        self.light = None
        if light.enabled:
            seed = round(self.params.anchors.min_seed_area * self.width * self.height)
            self.light = LightAdaptation(
                self.grid_background,
                light,
                self.step,
                self.kernel,
                seed // self.step**2,
                self.params.motion.k,
            )
        self.calibration = calibration
        self.following = None
        if calibration is not None and self.camera is not None:
            grid = self.grid_background.shape
            self.following = FollowingBackground(
                calibration.mosaic, self.camera, self.step, grid, self.params.view, calibration.lag
            )
        self.subtraction = background_of(
            self.grid_background,
            self.kernel,
            self.light,
            self.following,
            self.still_pose,
            self._grid_K,
            self.step,
            self._grid_size,
        )
        log.info("background %s", describe(model))

    @property
    def still_pose(self) -> CameraPose | None:
        """The pose of a calibration with a still head: frames taken there use the per-pixel
        model (None: a still camera, or a head that moved during the calibration)."""
        return None if self.calibration is None else self.calibration.still_pose

    @property
    def _grid_shape(self) -> tuple[int, int]:
        """(rows, columns) of the grid the frames are worked on."""
        return grid_shape(self.width, self.height, self.step)

    @property
    def _grid_size(self) -> tuple[float, float]:
        return self.width / self.step, self.height / self.step

    # -- frames -------------------------------------------------------------------------------

    def foreground(self, frame: PerceptionFrame) -> np.ndarray | None:
        """The noise-reduced 0/255 foreground of one frame alone (None for a bad frame), at
        full resolution: :meth:`process` computes the same mask (on its grid) and goes on to
        regions, motion and anchors. A grid frame's mask is of its grid, each grid pixel
        repeated over its block."""
        if self.background is None or self.grid_background is None:
            raise NotCalibrated("calibrate or load a background first")
        ycc = self._grid_ycc(frame)
        if isinstance(ycc, str):
            log.error("frame skipped: %s", ycc)
            return None
        if self.grid_frames:
            mask = open_mask(self.grid_background.classify(ycc), self.kernel)
            return _upsample(mask, self.step, (self.height, self.width)) * np.uint8(255)
        assert isinstance(frame, np.ndarray)  # (checked by _grid_ycc)
        mask = open_mask(self.background.classify(to_ycrcb(frame)), self.kernel)
        return mask * np.uint8(255)

    def process(
        self,
        frame: PerceptionFrame,
        t: float,
        pose: CameraPose | None = None,
        pose_fresh: bool = True,
        known: Sequence[np.ndarray] = (),
    ) -> FrameResult:
        """Percepts and anchors of one frame (a BGR image, or a :class:`GridFrame` when the
        background was calibrated on those) taken at time ``t`` (seconds), by a camera at
        ``pose`` (None: where it was for the calibration); ``pose_fresh`` False: the pose may be
        off (:data:`STALE_HOLD`). ``known``: the corners (8, 3) in the ground frame of each
        known object (the marker boxes): no anchor is born of what the frame shows of them
        (:mod:`.known`)."""
        if self.subtraction is None or self.motion is None:
            raise NotCalibrated("calibrate or load a background before processing frames")
        ycc = self._grid_ycc(frame)
        if isinstance(ycc, str):
            log.error("frame at t=%.3f skipped: %s", t, ycc)
            return FrameResult(
                percept_set=empty(self.coding.shape),
                anchors=self._last,
                masks=None,
                t=t,
                skipped=True,
            )
        # -- the background (fixed, lit, or a moving head's view): the frame in the
        # calibration's light where the light is adapted, its foreground, the quiet background
        # maintained.
        background = self.subtraction
        seen = background.foreground(ycc, pose, self._pose, self.tracker.boxes, t)
        ycc, fg, pose = seen.ycc, seen.fg, seen.pose
        tracker = self.tracker
        tracker.histograms = background.recolour(tracker.histograms, tracker.boxes, seen)
        before = self._pose
        turn = self._turn(before, pose)
        moved = self.motion.update(ycc, self._grid_turn(turn), seen.upper)
        background.maintain(seen, moved, t)
        if pose is not None:
            self._pose = pose
        # While a jump of the foreground is held, what changed may be the light or a body
        # passing close to the lens, not the objects; with a pose that may be off, the view:
        # the anchors stand as they were.
        held = self._stale(pose is not None and not pose_fresh, t)
        anchored = not (held or background.holding(seen))
        if anchored:
            # The turn since the tracker's last frame (not the same as the previous frame's
            # after frames whose anchors were held).
            self.tracker.predict(pose, turn if self.tracker.pose is before else None)
        found, class_ids = self._segment(fg, ycc, anchored)
        if anchored:
            self._last = self.tracker.update(found.percepts, moved, t, known)
        unknown = seen.unknown_fraction  # (before the learning, which makes it known)
        if not held:
            background.learn(seen, moved, self.tracker.boxes, t)
        masks = Masks((self.height, self.width), fg, moved, found.regions, found.classes, class_ids)
        return FrameResult(
            percept_set=found.percepts,
            anchors=self._last,
            masks=masks,
            t=t,
            light=background.status,
            unknown_fraction=unknown,
        )

    def _stale(self, stale: bool, t: float) -> bool:
        """Whether a frame at ``t`` whose pose is ``stale`` leaves the anchors as they stand
        (:data:`STALE_HOLD`)."""
        if not stale:
            self._stale_since = None
            return False
        if self._stale_since is None:
            self._stale_since = t
        return t - self._stale_since <= STALE_HOLD

    def _turn(self, before: CameraPose | None, pose: CameraPose | None) -> np.ndarray | None:
        """The homography (3x3) from the pixels of the view from ``before`` to those of the view
        from ``pose``, or None when there are not two poses or they are the same: computed
        once a frame for the previous frame's warp and the anchors' boxes."""
        if self.camera is None or pose is None or before is None or same_pose(before, pose):
            return None
        return view_homography(self.camera.K, before, pose)

    def _grid_turn(self, turn: np.ndarray | None) -> np.ndarray | None:
        """The camera ``turn`` (:meth:`_turn`) between the grids of the previous frame and this
        one, which the motion brings the previous frame through; None when it moves no pixel
        of the grid by a tenth (or the compensation is off)."""
        if turn is None or not self.params.view.compensate:
            return None
        H = on_grid(turn, self.step)
        return None if moves_little(H, self._grid_size) else H

    def _segment(
        self, fg: np.ndarray, ycc: np.ndarray, anchored: bool
    ) -> tuple[Segmentation, tuple[str, ...]]:
        """The regions of the foreground ``fg`` and their percepts, cut by the models' colours
        (after the tracker's :meth:`~.AnchorTracker.predict`; not when not ``anchored``: the frame
        is not for the anchors), and the models' ids in class order."""
        ids: list[str] = []
        if self.params.split.enabled and anchored:  # (the remembered anchors in view looked up)
            ids, boxes, histograms = self.tracker.split_models()
        if not ids:
            boxes, histograms = self.segmenter.no_models
        return self.segmenter(fg, ycc, boxes, histograms), tuple(ids)

    def _grid_ycc(self, frame: object) -> np.ndarray | str:
        """The YCrCb image of ``frame`` on the grid, or why it cannot be processed."""
        if isinstance(frame, GridFrame):
            image, shape = frame.ycc, (*self._grid_shape, 3)
            if not self.grid_frames and self.step > 1:
                return "a grid frame, but the background was calibrated on full-size frames"
            if frame.step != self.step:
                return f"a grid frame of step {frame.step}, expected step {self.step}"
        elif isinstance(frame, np.ndarray):
            image, shape = frame, (self.height, self.width, 3)
            if self.grid_frames:
                return "a full-size frame, but the background was calibrated on grid frames"
        else:
            return f"not an image but {type(frame).__name__}"
        if image.dtype != np.uint8:
            return f"pixels are {image.dtype}, not uint8"
        if image.shape != shape:
            return f"shape {image.shape}, expected {shape}"
        return grid_ycrcb(frame, self.step)
