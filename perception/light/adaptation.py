"""The per-frame adaptation of one background model to the light of a session.

For every frame, before the foreground test: fit the photometry on the sparse grid of pixels
that were background in the previous frame and lie in no anchor's box, map the frame to the
calibration's light, classify it, drop shadows, watch for sudden changes (re-learning outside
the anchors when the compensation cannot explain one and the view has come to rest, holding the
foreground outside the anchors back until then), reduce noise, and re-learn ghosts. After
the motion of the frame is known: mark busy pixels and maintain the quiet ones.

The model adapted is a copy of the calibration, so the saved calibration and
:meth:`Perception.foreground` (one frame alone) keep the learned model as it was.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from percept.perception.colour import Coding
from percept.perception.light.adaptation_kernels import light_after, light_frame, view_samples
from percept.perception.light.foreground import opencv_fuses, view_foreground
from percept.perception.light.maintenance import (
    GHOST_EVERY,
    GHOST_HOLD,
    RING,
    Maintenance,
    box_mask,
    changed,
    relearn,
)
from percept.perception.light.photometry.change import Change, ChangeDetector
from percept.perception.light.photometry.photometric import (
    CENTRE,
    HOLD,
    IDENTITY,
    MIN_SPREAD,
    Photometry,
    after_fit,
    fit,
    on_grid,
    sample_step,
)
from percept.perception.params import LightParams
from percept.perception.segmentation.background import BackgroundModel
from percept.perception.tracking.motion import Motion, open_mask
from percept.perception.view.follow import FrameView

MIN_INLIERS = 0.6
"""Share of the samples a photometric fit must keep to be taken (see
:meth:`LightAdaptation.foreground`). Real video's
noise and compression trim more than rendered frames: at 0.7, fits of MOT15 TUD-Stadtmitte's
frames were refused and two anchors were made on no person."""


@dataclass(frozen=True)
class LightStatus:
    """The light as one frame saw it, for the status of a daemon."""

    gain: tuple[float, float, float]
    """Y, Cr, Cb gain of the frame relative to the calibration (0.6: 60 % of its light)."""
    offset: tuple[float, float, float]
    """Y, Cr, Cb offset, grey levels."""
    steady: bool
    """No sudden change in the last ``settle`` seconds."""
    changed: bool
    """A sudden change was seen in this frame."""
    last_change: float | None
    """Frame time of the last sudden change (None: none since calibration)."""
    changes: int
    """Sudden changes since calibration."""
    relearned: int
    """Times the background was re-learned outside the anchors."""
    ghosts: int
    """Ghost regions re-learned."""

    def as_dict(self) -> dict[str, object]:
        """JSON-able, for a status message."""
        return {
            "gain": [round(g, 3) for g in self.gain],
            "offset": [round(o, 2) for o in self.offset],
            "steady": self.steady,
            "changed": self.changed,
            "last_change": None if self.last_change is None else round(self.last_change, 3),
            "changes": self.changes,
            "relearned": self.relearned,
            "ghosts": self.ghosts,
        }


class LightAdaptation:
    """Keeps a copy of ``calibrated`` valid through the light of a session.

    ``step`` is the grid the frames come on (boxes are in image pixels); ``kernel`` the noise
    reduction of the foreground; ``min_seed`` the smallest new anchor (grid pixels): smaller
    regions are not tested for ghosts, and an anchor is recoloured from a quarter of it;
    ``motion_k`` the motion threshold (a ghost is still).
    """

    def __init__(
        self,
        calibrated: BackgroundModel,
        params: LightParams,
        step: int,
        kernel: np.ndarray | None,
        min_seed: int,
        motion_k: float,
    ) -> None:
        self.params = params
        self.model = BackgroundModel(calibrated.mean.copy(), calibrated.sigma, calibrated.params)
        self.step, self.kernel = step, kernel
        self.min_seed = max(min_seed, 1)
        shape = self.model.shape
        self.sample = sample_step(shape, params.samples)
        self._expected: np.ndarray | None = None
        """The model's mean on the fit's sample grid (None: to be taken again, the mean changed)."""
        self._nothing = np.zeros(shape, np.uint8)  # no foreground: the fit's first frame
        self.changes = ChangeDetector(params)
        self.maintenance = Maintenance(shape, params)
        self.photometry: Photometry = IDENTITY
        self._previous: np.ndarray | None = None  # last frame's foreground before noise reduction
        self._anchored = np.zeros(shape, bool)
        self._frame: np.ndarray | None = None  # the last frame, in the calibration's light
        self.moving = np.clip(np.floor(self.model.scale(motion_k)), 0, 255).astype(np.uint8)
        """Grey levels a pixel must change by between frames to count as moving (the motion
        test's bound)."""
        self._changed = False
        self._relearned = 0
        self.relearned_now = False
        """The last frame re-learned the background: the anchors' colours are out of date."""
        self._ghosts = 0
        self._ghosts_tested_at = -math.inf
        self._background_at = np.zeros(shape)
        """Time each pixel was last background (before noise reduction)."""
        self._t = 0.0

    def foreground(
        self, ycc: np.ndarray, boxes: np.ndarray, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The frame in the calibration's light and its 0/1 noise-reduced foreground, for the
        YCrCb frame ``ycc`` (on the grid) at time ``t``, with the anchors' ``boxes``: two
        compiled calls (:mod:`.adaptation_kernels`) with the opening between them."""
        p, model = self.params, self.model
        anchored = self._anchored
        if self._expected is None:
            self._expected = on_grid(model.mean, self.sample)
        previous = self._previous
        frame, raw = np.empty_like(ycc), np.empty(ycc.shape[:2], np.uint8)
        # The photometry is fitted on the sparse grid of confident background pixels (all
        # pixels outside anchors when there is no last frame to tell them). When less than a
        # tenth of the grid was background in the last frame, it stays as it was: a body close
        # to the lens covers the view, and a fit on what is left would take its colours for the
        # light (at 15 fps a person crossing a metre from the camera gave a gain of 0.1,
        # reported as a switch). So it does when the fit keeps fewer than MIN_INLIERS of the
        # samples: light changes every pixel alike, so nearly all fit; where the samples are
        # part floor, part a body that covered it since the last frame, the fit follows one
        # and drops the other.
        fitted, inliers, compensated, share = light_frame(
            ycc,
            boxes,
            self.step,
            anchored,
            p.compensation,
            self._expected,
            self._nothing if previous is None else previous,
            self.sample,
            self.photometry.fitted,
            self.photometry.inliers,
            0.0 if previous is None else 0.1,
            MIN_INLIERS,
            CENTRE,
            MIN_SPREAD,
            HOLD,
            opencv_fuses(),
            model.lower,
            model.upper,
            model.mean,
            model.sigma,
            model.params.sigma_min,
            p.shadows,
            p.shadow_darkest,
            p.shadow_chroma,
            frame,
            raw,
        )
        self.photometry = after_fit(self.photometry, fitted, inliers)
        if compensated:
            ycc = frame
        change = self.changes.update(
            t, self.photometry.gain[0], share, lambda: self._moved(ycc, raw, anchored)
        )
        self._changed = change is not Change.NONE
        self.relearned_now = change is Change.UNEXPLAINED
        if self.relearned_now:
            relearn(model, ycc, ~anchored)
            self._expected = None
            raw[~anchored] = 0
            self._relearned += 1
        fg = open_mask(raw, self.kernel)
        holding = self.holding
        self._ghosts_tested_at, ghosts, found = light_after(
            fg,
            raw,
            anchored,
            holding,
            p.ghosts,
            float(t),
            self._ghosts_tested_at,
            GHOST_EVERY,
            self.min_seed,
            ycc,
            model.mean,
            self._background_at,
            t - GHOST_HOLD,
            ycc if self._frame is None else self._frame,
            self.moving,
            float(p.ghost_match),
            RING,
            self.maintenance.busy,
        )
        if found:
            relearn(model, ycc, ghosts)
            self._expected = None
            self._ghosts += 1
        if not holding:  # the fit keeps to the background from before a jump
            self._previous = raw
        self._frame = ycc
        self._t = t
        return ycc, fg

    def view_foreground(
        self, ycc: np.ndarray, view: FrameView, boxes: np.ndarray, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`foreground` for a frame of the moving head, whose background is ``view``
        (brought from the map over directions): the photometry fitted on the view's known
        pixels outside the anchors' ``boxes`` against the middle of its bounds, sudden changes
        of the gain reported. Nothing is re-learned, held or maintained here: that is the
        per-pixel model's, and the map learns what it does not know on its own."""
        p = self.params
        if p.compensation:
            frame, middle, excluded = view_samples(
                ycc, boxes, self.step, view.known, view.lower, view.upper, self.sample
            )
            self.photometry = fit(
                frame,
                middle,
                excluded,
                np.zeros(excluded.shape, np.uint8),
                current=self.photometry,
                min_inliers=MIN_INLIERS,
            )
        ycc, raw = view_foreground(ycc, self.photometry, view.lower, view.upper)
        change = self.changes.update(t, self.photometry.gain[0], 0.0, lambda: 0.0)
        self._changed = change is not Change.NONE
        self.relearned_now = False
        self._previous, self._frame, self._t = None, None, t  # per-pixel frames no longer hold
        return ycc, open_mask(raw, self.kernel)

    @property
    def holding(self) -> bool:
        """A sudden jump of the foreground is held (:mod:`.photometry.change`): no new anchor."""
        return self.changes.holding

    def _moved(self, ycc: np.ndarray, raw: np.ndarray, anchored: np.ndarray) -> float:
        """Share of the foreground outside the ``anchored`` pixels (on the sparse grid) that
        changed since the last frame by more than the motion test's bound."""
        if self._frame is None:  # nothing to compare with: not known to be still
            return 1.0
        s = self.sample
        fg = (raw[::s, ::s] > 0) & ~anchored[::s, ::s]
        if not fg.any():
            return 0.0
        moved = changed(ycc[::s, ::s], self._frame[::s, ::s], self.moving[::s, ::s])
        return float(moved[fg].mean())

    def maintain(self, ycc: np.ndarray, moved: Motion, t: float) -> None:
        """After the frame's motion is known: mark moving pixels busy and, when due, let the
        quiet ones follow ``ycc`` (the frame in the calibration's light)."""
        if not self.maintenance.due(t):
            return
        self.maintenance.mark(moved.mask(), t)
        self.maintenance.step(self.model, ycc, self._anchored, t)
        self._expected = None

    def recolour(
        self, histograms: np.ndarray, boxes: np.ndarray, ycc: np.ndarray, fg: np.ndarray
    ) -> np.ndarray:
        """The anchors' colour models (n, factors, bins) after a change of light the
        compensation could not explain: each taken from the foreground inside its box in this
        frame, so that the anchors are kept by position while their colours are seen anew
        (unchanged where its box holds too little foreground)."""
        out = histograms.copy()
        coding = Coding.of_histograms(histograms)
        for i, box in enumerate(boxes):
            inside = box_mask(box[None], fg.shape, self.step) & (fg > 0)
            if inside.sum() < self.min_seed // 4 + 1:
                continue
            out[i] = coding.histograms(ycc[inside])
        return out

    @property
    def status(self) -> LightStatus:
        """The light as of the last frame."""
        last = self.changes.last
        ph = self.photometry
        return LightStatus(
            gain=ph.gain,
            offset=ph.offset,
            steady=self.changes.steady(self._t),
            changed=self._changed,
            last_change=None if last == -np.inf else last,
            changes=self.changes.count,
            relearned=self._relearned,
            ghosts=self._ghosts,
        )
