"""Object anchors (§4.4): persistent, Kalman-filtered models of the objects in view.

Each frame: the filters predict; the pipeline splits the foreground with the models' colours;
then :meth:`AnchorTracker.update` associates every percept with the model of highest score
``s = s_space * s_color`` (thresholds loosened for models in motion), combines the percepts of each
model and corrects its filter and histograms, turns the unassociated percepts of each foreground
region into one seed for a new model where nothing moves, and deletes models not seen for
``max_absence`` seconds. A model's id (``o1``, ``o2``, ...) never changes while it lives.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from percept.perception.kalman import BoxFilters
from percept.perception.kernels.association import best_models
from percept.perception.motion import Motion
from percept.perception.params import AnchorParams
from percept.perception.percepts import PerceptSet, combine


@dataclass(frozen=True)
class Anchor:
    """One object model as it stands after a frame: the world model's unit."""

    id: str
    """Persistent id, ``o`` followed by a number; never reused within a tracker."""
    bbox: tuple[float, float, float, float]
    """left, top, width, height in pixels, from the filter state."""
    histograms: np.ndarray
    """(3, m) normalised Y, Cr, Cb histograms of the model."""
    created: float
    """Time (the frames' clock, seconds) the model was created."""
    last_seen: float
    """Time of the last frame with a percept associated to it."""
    stamp: float
    """Time of the frame this snapshot describes."""
    in_motion: bool
    """Motion was detected inside its predicted box in this frame."""
    velocity: tuple[float, float]
    """Rate of the box centre (dx, dy) in pixels per frame, from the filter state."""
    pixels: int
    """Pixels of the percepts last associated with it."""

    @property
    def age(self) -> float:
        """Seconds since the model was created."""
        return self.stamp - self.created

    @property
    def visible(self) -> bool:
        """A percept was associated with it in this frame."""
        return self.last_seen == self.stamp

    @property
    def number(self) -> int:
        """The numeric part of the id (for MOTChallenge files)."""
        return int(self.id[1:])


class AnchorTracker:
    """The set of object models and the association, update, creation and deletion rules."""

    def __init__(self, params: AnchorParams, width: int, height: int, bins: int) -> None:
        self.params = params
        self.width, self.height = width, height
        self.diagonal = math.hypot(width, height)
        self.min_seed_pixels = params.min_seed_area * width * height
        self.filters = BoxFilters(params.q, params.r, params.p0_position, params.p0_velocity)
        self.histograms = np.zeros((0, 3, bins))
        self.ids: list[str] = []
        self.created = np.zeros(0)
        self.last_seen = np.zeros(0)
        self.pixels = np.zeros(0, np.intp)
        self.in_motion = np.zeros(0, bool)
        self._next = 1

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def created_count(self) -> int:
        """How many models were ever created (the last id's number)."""
        return self._next - 1

    @property
    def boxes(self) -> np.ndarray:
        """(n, 4) current boxes (left, top, width, height) of the models, from the filters."""
        x = self.filters.x
        return np.concatenate([x[:, :2] - x[:, 2:4] / 2, x[:, 2:4]], axis=1)

    def predict(self) -> None:
        """Advance every filter by one frame (call before splitting with :attr:`boxes`)."""
        self.filters.predict()
        np.maximum(self.filters.x[:, 2:4], 1.0, out=self.filters.x[:, 2:4])

    def update(self, percepts: PerceptSet, motion: Motion, t: float) -> list[Anchor]:
        """Associate, correct, create and delete after :meth:`predict`; the anchors after it."""
        p = self.params
        self.in_motion = motion.fraction(self.boxes) > 0
        best = self.associate(percepts)
        hit = best >= 0
        if hit.any():
            models, merged = _merge_per_model(best[hit], _rows(percepts, hit), len(self))
            self.filters.update(models, _measurement(merged.boxes))
            h = (1 - p.alpha) * self.histograms[models] + p.alpha * merged.histograms
            # A new array each frame: the snapshots handed out keep views of the old one.
            self.histograms = self.histograms.copy()
            self.histograms[models] = h / h.sum(axis=2, keepdims=True)
            self.last_seen[models] = t
            self.pixels[models] = merged.counts
        if not hit.all():
            self._create(_rows(percepts, ~hit), motion, t)
        alive = t - self.last_seen <= p.max_absence
        if not alive.all():
            self._keep(alive)
        return self.anchors(t)

    def associate(self, percepts: PerceptSet) -> np.ndarray:
        """Model index of each percept (highest non-zero score), or -1."""
        p = self.params
        return best_models(
            percepts.boxes,
            percepts.histograms,
            self.filters.x,
            self.histograms,
            self.in_motion,
            np.array([p.t_space, p.t_space_motion]),
            np.array([p.t_color, p.t_color_motion]),
            self.diagonal,
        )

    def anchors(self, t: float) -> list[Anchor]:
        """Snapshots of all models at frame time ``t``."""
        return [
            Anchor(
                id=i,
                bbox=tuple(b),
                histograms=h,
                created=c,
                last_seen=s,
                stamp=t,
                in_motion=moving,
                velocity=tuple(v),
                pixels=n,
            )
            for i, b, h, c, s, moving, v, n in zip(
                self.ids,
                self.boxes.tolist(),
                self.histograms,
                self.created.tolist(),
                self.last_seen.tolist(),
                self.in_motion.tolist(),
                self.filters.x[:, 4:6].tolist(),
                self.pixels.tolist(),
                strict=True,
            )
        ]

    def _create(self, loose: PerceptSet, motion: Motion, t: float) -> None:
        """One new model per foreground region from its unassociated percepts, where still."""
        regions, groups = np.unique(loose.regions, return_inverse=True)
        seeds = combine(groups, len(regions), loose)
        still = motion.fraction(seeds.boxes) <= self.params.max_seed_motion
        ok = still & (seeds.counts >= self.min_seed_pixels)
        if not ok.any():
            return
        n = int(ok.sum())
        self.filters.add(_measurement(seeds.boxes[ok]))
        self.histograms = np.concatenate([self.histograms, seeds.histograms[ok]])
        self.ids += [f"o{self._next + i}" for i in range(n)]
        self._next += n
        self.created = np.concatenate([self.created, np.full(n, t)])
        self.last_seen = np.concatenate([self.last_seen, np.full(n, t)])
        self.pixels = np.concatenate([self.pixels, seeds.counts[ok]])
        self.in_motion = np.concatenate([self.in_motion, np.zeros(n, bool)])

    def _keep(self, rows: np.ndarray) -> None:
        self.filters.keep(rows)
        self.histograms = self.histograms[rows]
        self.ids = [i for i, k in zip(self.ids, rows, strict=True) if k]
        self.created, self.last_seen = self.created[rows], self.last_seen[rows]
        self.pixels, self.in_motion = self.pixels[rows], self.in_motion[rows]


def _merge_per_model(
    best: np.ndarray, percepts: PerceptSet, n_models: int
) -> tuple[np.ndarray, PerceptSet]:
    """The models that got percepts, and their percepts combined (one row per model)."""
    if len(best) == 1 or np.bincount(best, minlength=n_models).max() == 1:
        return best, percepts  # the usual case: at most one percept per model
    models, groups = np.unique(best, return_inverse=True)
    return models, combine(groups, len(models), percepts)


def _rows(percepts: PerceptSet, rows: np.ndarray) -> PerceptSet:
    return PerceptSet(
        boxes=percepts.boxes[rows],
        histograms=percepts.histograms[rows],
        counts=percepts.counts[rows],
        regions=percepts.regions[rows],
    )


def _measurement(boxes: np.ndarray) -> np.ndarray:
    """(x, y, w, h) with x, y the centre, from (left, top, width, height)."""
    return np.concatenate([boxes[:, :2] + boxes[:, 2:] / 2, boxes[:, 2:]], axis=1)
