"""The background a frame is told from, behind one interface whatever it keeps inside.

:class:`Perception` chooses one :class:`Background` when its background is calibrated or
loaded (:func:`background_of`) and asks it for every frame's foreground, as OpenCV's
``BackgroundSubtractor`` is one object whose ``apply(frame)`` gives a mask:

- :class:`FixedBackground`: the per-pixel model learned at calibration, then frozen (the
  chapter's);
- :class:`LitBackground`: the per-pixel model kept valid through a session's light
  (:mod:`percept.perception.light`): the frame brought into the calibration's light, shadows
  and ghosts dropped, quiet pixels maintained, re-learned after a change the light cannot
  explain;
- :class:`ViewBackground`: a moving head's background over viewing directions
  (:mod:`percept.perception.view`), brought into each frame's view (and into the calibration's
  light when the light is adapted), its ghosts forgotten and learned anew where the light
  is adapted with ghosts (:mod:`percept.perception.view.ghosts`). A frame at the pose of a
  calibration with a still head is told from the per-pixel background (fixed or lit)
  instead: that choice is made per frame, here.

Each frame, :meth:`Background.foreground` comes first; the other calls are about the frame it
returned (:class:`Foreground`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from percept.kinematics.pose import CameraPose
from percept.perception.light.adaptation import LightAdaptation, LightStatus
from percept.perception.segmentation.background import BackgroundModel
from percept.perception.tracking.motion import Motion, open_mask
from percept.perception.view.follow import FollowingBackground, FrameView, same_view
from percept.perception.view.ghosts import ViewGhosts

log = logging.getLogger("percept.perception")


@dataclass(frozen=True)
class Foreground:
    """What a background made of one frame."""

    ycc: np.ndarray
    """The frame (YCrCb, on the grid), in the calibration's light where the light is adapted."""
    fg: np.ndarray
    """0/1 foreground after noise reduction."""
    pose: CameraPose | None
    """The camera pose at the image's time (None: the frame came without one)."""
    view: FrameView | None = None
    """The moving head's background of this frame's view (None: the per-pixel model's frame)."""

    @property
    def upper(self) -> np.ndarray | None:
        """The motion's difference bounds of this view (None: the calibration's)."""
        return None if self.view is None else self.view.moved

    @property
    def unknown_fraction(self) -> float:
        """Fraction of the frame whose background is not known yet (never foreground there)."""
        return 0.0 if self.view is None else self.view.unknown_fraction


class Background(Protocol):
    """The background :meth:`Perception.process` tells each frame's foreground from."""

    def foreground(
        self,
        ycc: np.ndarray,
        pose: CameraPose | None,
        previous: CameraPose | None,
        boxes: np.ndarray,
        t: float,
    ) -> Foreground:
        """The foreground of frame ``ycc`` taken at ``t`` by a camera at ``pose`` (None: where
        it was for the ``previous`` frame), the anchors' ``boxes`` (n, 4) in its pixels."""
        ...

    def recolour(self, histograms: np.ndarray, boxes: np.ndarray, seen: Foreground) -> np.ndarray:
        """The anchors' colour models after this frame: new ones where the background was
        re-learned in it (their colours changed with the light), else ``histograms``."""
        ...

    def maintain(self, seen: Foreground, moved: Motion, t: float) -> None:
        """Let the background follow the frame where it is quiet."""
        ...

    def holding(self, seen: Foreground) -> bool:
        """A jump of this frame's foreground is held: it is not for the anchors."""
        ...

    def learn(self, seen: Foreground, moved: Motion, boxes: np.ndarray, t: float) -> None:
        """Learn what this frame shows of the background not known yet."""
        ...

    @property
    def status(self) -> LightStatus | None:
        """The light as the last frame saw it (None: the light is not adapted)."""
        ...


class FixedBackground:
    """The per-pixel model learned at calibration, then frozen."""

    def __init__(self, model: BackgroundModel, kernel: np.ndarray | None) -> None:
        self.model = model
        self.kernel = kernel

    def foreground(
        self,
        ycc: np.ndarray,
        pose: CameraPose | None,
        previous: CameraPose | None,
        boxes: np.ndarray,
        t: float,
    ) -> Foreground:
        return Foreground(ycc, open_mask(self.model.classify(ycc), self.kernel), pose)

    def recolour(self, histograms: np.ndarray, boxes: np.ndarray, seen: Foreground) -> np.ndarray:
        return histograms

    def maintain(self, seen: Foreground, moved: Motion, t: float) -> None:
        return

    def holding(self, seen: Foreground) -> bool:
        return False

    def learn(self, seen: Foreground, moved: Motion, boxes: np.ndarray, t: float) -> None:
        return

    @property
    def status(self) -> LightStatus | None:
        return None


class LitBackground:
    """The per-pixel model kept valid through a session's light."""

    def __init__(self, light: LightAdaptation) -> None:
        self.light = light

    def foreground(
        self,
        ycc: np.ndarray,
        pose: CameraPose | None,
        previous: CameraPose | None,
        boxes: np.ndarray,
        t: float,
    ) -> Foreground:
        ycc, fg = self.light.foreground(ycc, boxes, t)
        return Foreground(ycc, fg, pose)

    def recolour(self, histograms: np.ndarray, boxes: np.ndarray, seen: Foreground) -> np.ndarray:
        # Re-learned: the anchors are kept by position while their colours change.
        if not self.light.relearned_now:
            return histograms
        return self.light.recolour(histograms, boxes, seen.ycc, seen.fg)

    def maintain(self, seen: Foreground, moved: Motion, t: float) -> None:
        self.light.maintain(seen.ycc, moved, t)

    def holding(self, seen: Foreground) -> bool:
        return self.light.holding

    def learn(self, seen: Foreground, moved: Motion, boxes: np.ndarray, t: float) -> None:
        return

    @property
    def status(self) -> LightStatus | None:
        return self.light.status


class ViewBackground:
    """A moving head's background over viewing directions, brought into each frame's view;
    ``still`` (fixed or lit) for frames without a pose, or at the pose of a calibration with a
    still head (``still_pose``). Against a view the light is not maintained, nor its jumps
    held: the frame is only brought into the calibration's light."""

    def __init__(
        self,
        following: FollowingBackground,
        still: FixedBackground | LitBackground,
        light: LightAdaptation | None,
        kernel: np.ndarray | None,
        still_pose: CameraPose | None,
        grid_K: np.ndarray,
        step: int,
        grid_size: tuple[float, float],
        ghosts: ViewGhosts | None = None,
    ) -> None:
        self.following = following
        self.still = still
        self.light = light
        self.kernel = kernel
        self.still_pose = still_pose
        self.grid_K = grid_K
        """The camera matrix of the grid of every ``step``-th pixel the frames are worked on,
        and its size (width, height): what tells two poses apart."""
        self.step = step
        self.grid_size = grid_size
        self.ghosts = ghosts
        """The ghost test over the map (None: ghosts are left as they are)."""

    def _view(self, ycc: np.ndarray, pose: CameraPose | None) -> FrameView | None:
        """The background of this frame's view, or None where the per-pixel model holds."""
        if pose is None:
            return None
        still = self.still_pose
        if still is not None and same_view(self.grid_K, self.grid_size, still, pose):
            return None
        return self.following.view(pose, ycc[..., 0])

    def foreground(
        self,
        ycc: np.ndarray,
        pose: CameraPose | None,
        previous: CameraPose | None,
        boxes: np.ndarray,
        t: float,
    ) -> Foreground:
        view = self._view(ycc, pose if pose is not None else previous)
        if view is None:
            return self.still.foreground(ycc, pose, previous, boxes, t)
        if pose is not None:
            # The pose at the image's time: the previous frame's warp and the anchors'
            # prediction take that, not the pose of joint angles read a little before or after.
            pose = self.following.timed
        if self.light is not None:
            ycc, fg = self.light.view_foreground(ycc, view, boxes, t)
        else:
            fg = open_mask(view.classify(ycc), self.kernel)
        return Foreground(ycc, fg, pose, view)

    def recolour(self, histograms: np.ndarray, boxes: np.ndarray, seen: Foreground) -> np.ndarray:
        if seen.view is not None:
            return histograms
        return self.still.recolour(histograms, boxes, seen)

    def maintain(self, seen: Foreground, moved: Motion, t: float) -> None:
        if seen.view is None:
            self.still.maintain(seen, moved, t)

    def holding(self, seen: Foreground) -> bool:
        return seen.view is None and self.still.holding(seen)

    def learn(self, seen: Foreground, moved: Motion, boxes: np.ndarray, t: float) -> None:
        """Forget the directions of this frame's ghosts, and teach the mosaic the unknown
        directions of this frame seen quietly: no motion, no anchor (whose box may hide an
        object that is not background)."""
        view = seen.view
        if view is None:
            return
        if self.ghosts is not None:
            self.ghosts.mark(view, seen.fg, t)
            forgotten = self.ghosts.test(view, seen.ycc, seen.fg, moved, boxes, t)
            if forgotten:
                log.debug("forgot the ghost in %d directions at t=%.2f", forgotten, t)
        if view.unknown_fraction <= 0:
            return
        on_grid = np.ascontiguousarray(boxes / self.step, dtype=float)
        mosaic = self.following.mosaic
        learned = mosaic.learn(view.nearest, seen.ycc, moved, on_grid, view.known, t)
        if learned:
            log.debug("learned the background of %d directions at t=%.2f", learned, t)

    @property
    def status(self) -> LightStatus | None:
        return None if self.light is None else self.light.status


def background_of(
    model: BackgroundModel,
    kernel: np.ndarray | None,
    light: LightAdaptation | None,
    following: FollowingBackground | None,
    still_pose: CameraPose | None,
    grid_K: np.ndarray | None,
    step: int,
    grid_size: tuple[float, float],
) -> Background:
    """The background of a calibration: its per-pixel ``model`` (on the grid), fixed or kept
    through the ``light``, and with ``following`` (a calibration with camera poses, ``grid_K``
    the camera matrix of the grid of every ``step``-th pixel) the moving head's view
    background around it."""
    still: FixedBackground | LitBackground
    still = FixedBackground(model, kernel) if light is None else LitBackground(light)
    if following is None or grid_K is None:
        return still
    ghosts = None
    if light is not None and light.params.ghosts:
        mosaic = following.mosaic
        ghosts = ViewGhosts(mosaic, light.params.ghost_match, light.min_seed, step)
    return ViewBackground(
        following, still, light, kernel, still_pose, grid_K, step, grid_size, ghosts
    )
