"""Object anchors (§4.4): persistent, Kalman-filtered models of the objects in view.

Each frame: the filters predict; the pipeline splits the foreground with the models' colours;
then :meth:`AnchorTracker.update` associates every percept with the model of highest score
``s = s_space * s_color`` (thresholds loosened for models in motion), combines the percepts of each
model and corrects its filter and histograms, turns the unassociated percepts of each foreground
region into one seed for a new model where nothing moves, and deletes models not seen for
``max_absence`` seconds. A model's id (``o1``, ``o2``, ...) never changes while it lives.

With the camera model and each frame's camera pose, the filters follow the head: before each
prediction their states are carried from the last frame's view into this one by the homography
between the two views (:meth:`~percept.perception.tracking.kalman.BoxFilters.warp`), and anchors
out of view or hidden are remembered rather than deleted, and recognised when they come back
(:mod:`percept.perception.tracking.permanence.memory`). Without a pose, nothing of that happens.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.ground import view_homography
from percept.kinematics.pose import CameraPose, same_pose, wrap
from percept.perception.colour import Coding, hue
from percept.perception.params import AnchorParams
from percept.perception.segmentation.percepts import PerceptSet, combine
from percept.perception.tracking.anchors_kernels import blend, may_double
from percept.perception.tracking.association_kernels import colour_similarity
from percept.perception.tracking.kalman import BoxFilters
from percept.perception.tracking.known import KNOWN_COVER, KnownOutlines, known_cover
from percept.perception.tracking.motion import Motion
from percept.perception.tracking.permanence.memory import (
    AnchorMemory,
    Remembered,
    covered,
    touches_border,
)
from percept.perception.tracking.update_kernels import track

PART = 0.1
"""While the head turns, a new piece of a region a model takes is a part of that model's object
(no new anchor) when this much of its box lies in the model's box and its hue is the model's
(:data:`SAME_HUE`): a face in another shade, or the object growing into view. Another object
that stands against it overlaps its box less, or has another hue."""
INSIDE = 0.5
"""While the head holds still (with a camera pose), a new piece of a region a model takes is a
part of that model's object when at least this much of its box lies in the model's box and its
hue is the model's: the shaded lower part of an object whose model was made from the lit part
the image's border left, say. (A second object in the same hue, put down more than half inside
the model's box, waits for its anchor until the two stand apart.)"""
SAME_HUE = math.radians(30.0)
"""Hues (:func:`~percept.perception.colour.hue`) closer than this may be shades of one colour:
a face lit more or less than the rest; the hues of the shipped objects' colours are 55 degrees
and more apart where they differ."""
MIN_CHROMA = 10.0
"""Grey levels of chroma below which a colour has no hue to tell (grey, black, white)."""
DOUBLE = 0.8
"""Two models seen in one frame are one object's when this much of the box of one of them lies
in the other's and their colours are one colour's (:meth:`AnchorTracker._merge_doubles`): two
objects of one colour, one in front of the other, are never told apart by the colour split
either, so the second model only lives on the first one's pixels."""
PIECE_GAP = 0.25
"""Two seeds of one frame are pieces of one object (:func:`pieces`) when their boxes are apart
by at most this share of the smaller box's width across and of its height down, in one colour:
a band of an object as bright as the floor behind it cuts its foreground in two (the lit top of
a grey ball and its shaded foot, the faces of a grey block), and each piece would otherwise get
an anchor of its own that the colour split keeps apart for as long as the object stays. Only
while the head holds still: while it turns, the view's foreground is in bits everywhere, and
bits taken together would be seeds of nothing."""
_NO_MOTION = np.zeros(0, bool)
"""What :func:`~.update_kernels.track` takes for the motion it counts itself."""


@dataclass(frozen=True)
class Anchor:
    """One object model as it stands after a frame: the world model's unit."""

    id: str
    """Persistent id, ``o`` followed by a number; never reused within a tracker."""
    bbox: tuple[float, float, float, float]
    """left, top, width, height in pixels, from the filter state."""
    histograms: np.ndarray
    """(factors, bins) normalised colour model (:class:`~percept.perception.colour.Coding`)."""
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
    whole: bool = False
    """Seen whole in this frame: its percepts clear of the image's border, its box clear of
    nearer anchors' boxes or touching them (known only with a camera pose)."""
    remembered: bool = False
    """Out of sight (out of view or hidden) and remembered: ``bbox`` is where its remembered
    ground position falls in this frame's view. Never :attr:`visible`."""

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


def snapshot(values: dict[str, object]) -> Anchor:
    """An :class:`Anchor` of ``values`` (a dict of its own, which names every field): the same
    record as ``Anchor(**values)``, made without the frozen dataclass's ``__init__``, which sets
    each field through ``object.__setattr__`` (3 µs an anchor, a fifth of the anchors' work per
    frame at 176x144 with 8 objects), and without passing keywords (a further 0.3 µs). The
    record stays frozen."""
    anchor = object.__new__(Anchor)
    object.__setattr__(anchor, "__dict__", values)
    return anchor


class AnchorTracker:
    """The set of object models and the association, update, creation and deletion rules."""

    def __init__(
        self,
        params: AnchorParams,
        width: int,
        height: int,
        coding: Coding,
        camera: CameraModel | None = None,
    ) -> None:
        self.params = params
        self.camera = camera
        self.memory = None if camera is None else AnchorMemory(params, camera, width, height)
        """The anchors out of sight (None without a camera model)."""
        self._outlines = None if camera is None else KnownOutlines(camera)
        self.pose: CameraPose | None = None
        """The camera pose of the frame being tracked (None: unknown, a still camera)."""
        self.turn: np.ndarray | None = None
        """The homography (3x3) from the previous frame's pixels to this frame's when the
        camera's pose changed between them, else None."""
        self.width, self.height = width, height
        self.diagonal = math.hypot(width, height)
        self.min_seed_pixels = params.min_seed_area * width * height
        self.filters = BoxFilters(params.q, params.r, params.p0_position, params.p0_velocity)
        self.histograms = np.zeros((0, *coding.shape))
        self.ids: list[str] = []
        self.created = np.zeros(0)
        self.last_seen = np.zeros(0)
        self.pixels = np.zeros(0, np.intp)
        self.in_motion = np.zeros(0, bool)
        self.whole = np.zeros(0, bool)
        self.cut = np.zeros(0, bool)
        """The percepts of each model in this frame reach the image's border."""
        self.away = np.zeros(0, bool)
        """Out of sight in some frame since each model was last seen: its box, which its
        filter's rates move on meanwhile, may drift back into view before it is deleted."""
        self._best = np.zeros(0, np.intp)
        """Each percept's model in the last frame (-1: none), before births and deaths."""
        self._next = 1
        self._t_space = np.array([params.t_space, params.t_space_motion])
        self._t_color = np.array([params.t_color, params.t_color_motion])
        """The association's thresholds (still, in motion), as :func:`~.update_kernels.track` takes
        them."""

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def created_count(self) -> int:
        """How many models were ever created (the last id's number)."""
        return self._next - 1

    @property
    def boxes(self) -> np.ndarray:
        """(n, 4) current boxes (left, top, width, height) of the models, from the filters."""
        return self.filters.boxes

    def split_models(self) -> tuple[list[str], np.ndarray, np.ndarray]:
        """Ids, boxes and histograms of the models the colour split tells apart (after
        :meth:`predict`): the tracker's, then the remembered anchors whose place is in view. An
        object that comes back into view touching another one is then cut out of that one's
        region by its colour, and the memory recognises the piece (:meth:`_create`)."""
        if self.memory is None or self.pose is None or not self.memory.remembered:
            return list(self.ids), self.boxes, self.histograms
        back, boxes = self.memory.in_view(self.pose)
        if not back:
            return list(self.ids), self.boxes, self.histograms
        return (
            self.ids + [r.id for r in back],
            np.concatenate([self.boxes, boxes]),
            np.concatenate([self.histograms, np.array([r.histograms for r in back])]),
        )

    def predict(self, pose: CameraPose | None = None, turn: np.ndarray | None = None) -> None:
        """Advance every filter by one frame taken from ``pose`` (call before splitting with
        :attr:`boxes`); when the pose moved since the last frame, carry the boxes into the new
        view first, through ``turn`` when the caller has that homography from the last pose's
        view to this one's (computed here otherwise)."""
        last, self.pose = self.pose, pose
        self.turn = None
        if (
            self.camera is not None
            and pose is not None
            and last is not None
            and not same_pose(last, pose)
        ):
            self.turn = view_homography(self.camera.K, last, pose) if turn is None else turn
            self.filters.warp(self.turn)
        self.filters.predict(min_size=1.0)

    def update(
        self, percepts: PerceptSet, motion: Motion, t: float, known: Sequence[np.ndarray] = ()
    ) -> list[Anchor]:
        """Associate, correct, create and delete (or remember) after :meth:`predict`; the
        anchors after it, then those remembered out of sight. ``known``: the corners (8, 3) in
        the ground frame of each known object (the marker boxes), of which no model is made
        (:meth:`_unknown`)."""
        p = self.params
        if self._track(percepts, motion, t):  # the usual frame: nothing born, lost or doubled
            alive = None
        else:
            best = self._best
            hit = best >= 0
            if not hit.all():
                loose = self._unknown(percepts.select(~hit), known)
                self._create(loose, motion, t, percepts.regions[hit], best[hit])
            alive = t - self.last_seen <= p.max_absence
            alive &= ~self._merge_doubles(t)
        self._follow(t, motion, alive)
        if alive is not None and not alive.all():
            self._keep(alive)
        if self.memory is None:
            return self.anchors(t)
        self.memory.forget_sightings(self.ids)
        return self.anchors(t) + self.remembered(t)

    def _track(self, percepts: PerceptSet, motion: Motion, t: float) -> bool:
        """The motion in the models' predicted boxes, the association and the correction in one
        compiled call (:func:`~.update_kernels.track`); whether that was the whole of the
        frame's update (nothing born, lost or doubled). Sets :attr:`in_motion` and
        :attr:`_best`, each percept's model or -1."""
        previous = motion.previous_in_one_view()
        if previous is not None:
            answered, steady = self._compiled(percepts, motion, previous, None, t)
            if answered:
                return steady
        # The first frame, a turn, the whole mask made, boxes that read much of the image.
        moving = motion.fraction(self.boxes) > 0
        return self._compiled(percepts, motion, motion.current, moving, t)[1]

    def _compiled(
        self,
        percepts: PerceptSet,
        motion: Motion,
        previous: np.ndarray,
        in_motion: np.ndarray | None,
        t: float,
    ) -> tuple[bool, bool]:
        """:func:`~.update_kernels.track` with the motion counted between ``previous`` and
        ``motion``'s frame, or given (``in_motion``); whether it answered, and ``steady``."""
        p, filters = self.params, self.filters
        answered, moving, best, histograms, cut, steady = track(
            motion.current,
            previous,
            motion.upper,
            motion.size,
            motion.step,
            in_motion is None,
            _NO_MOTION if in_motion is None else in_motion,
            percepts.boxes,
            percepts.histograms,
            percepts.counts,
            percepts.regions,
            filters.x,
            filters.cov,
            filters.r,
            self.histograms,  # (a new array comes back: the snapshots keep the old one)
            self._t_space,
            self._t_color,
            self.diagonal,
            p.alpha,
            self.last_seen,
            self.pixels,
            float(t),
            self.width,
            self.height,
            self.turn is not None,
            p.max_absence,
            DOUBLE,
        )
        if answered:
            self.in_motion, self._best, self.histograms, self.cut = moving, best, histograms, cut
        return answered, steady

    def _unknown(self, loose: PerceptSet, known: Sequence[np.ndarray]) -> PerceptSet:
        """The unassociated percepts that are not of a known object: less than
        :data:`~.known.KNOWN_COVER` of their box inside its image from the camera's pose. Only
        new models are kept from them: a model's percepts stay its own when it stands in front
        of a box, and the projection costs nothing in the usual frame, whose percepts are all
        the models'."""
        if not known or not len(loose) or self.pose is None or self._outlines is None:
            return loose
        outlines = self._outlines(known, self.pose)
        if not outlines:
            return loose
        return loose.select(known_cover(loose.boxes, outlines) < KNOWN_COVER)

    def anchors(self, t: float) -> list[Anchor]:
        """Snapshots of all models at frame time ``t``."""
        return [
            snapshot(
                {
                    "id": i,
                    "bbox": (x - w / 2, y - h / 2, w, h),  # as :attr:`boxes`, without the array
                    "histograms": hist,
                    "created": c,
                    "last_seen": s,
                    "stamp": t,
                    "in_motion": moving,
                    "velocity": (dx, dy),
                    "pixels": n,
                    "whole": whole,
                    "remembered": False,
                }
            )
            for i, (x, y, w, h, dx, dy, _, _), hist, c, s, moving, n, whole in zip(
                self.ids,
                self.filters.x.tolist(),
                self.histograms,
                self.created.tolist(),
                self.last_seen.tolist(),
                self.in_motion.tolist(),
                self.pixels.tolist(),
                self.whole.tolist(),
                strict=True,
            )
        ]

    def remembered(self, t: float) -> list[Anchor]:
        """Snapshots of the anchors out of sight at frame time ``t``."""
        if self.memory is None:
            return []
        return [
            snapshot(
                {
                    "id": r.id,
                    "bbox": r.bbox,
                    "histograms": r.histograms,
                    "created": r.created,
                    "last_seen": r.last_seen,
                    "stamp": t,
                    "in_motion": False,
                    "velocity": (0.0, 0.0),
                    "pixels": r.pixels,
                    "whole": False,
                    "remembered": True,
                }
            )
            for r in self.memory.remembered.values()
        ]

    def _follow(self, t: float, motion: Motion, alive: np.ndarray | None) -> None:
        """With a pose: note where the anchors seen whole stand, remember those about to be
        deleted (not ``alive``; None: none is) that went out of sight since last seen, and
        update the memory."""
        if self.memory is None or self.pose is None:
            return
        seen = self.last_seen == t
        boxes = self.boxes
        self.whole, out_of_sight = self.memory.follow(self.ids, boxes, seen, self.cut, self.pose)
        self.away = (self.away | out_of_sight) & ~seen
        leaving = [] if alive is None else np.flatnonzero(self.away & ~alive).tolist()
        for i in leaving:
            anchor_id = self.ids[i]
            self.memory.keep(
                Remembered(
                    id=anchor_id,
                    sighting=self.memory.sightings.get(anchor_id),
                    histograms=self.histograms[i].copy(),
                    created=float(self.created[i]),
                    last_seen=float(self.last_seen[i]),
                    pixels=int(self.pixels[i]),
                    bbox=tuple(boxes[i].tolist()),
                    glimpse=self.memory.glimpses.get(anchor_id),
                )
            )
        if self.memory.remembered:  # (else nothing to forget, and its arguments cost)
            self.memory.forget_doubles(
                [self.ids[i] for i in np.flatnonzero(seen)], self.histograms[seen]
            )
        self.memory.review(self.pose, t, boxes[seen], motion)

    def _create(
        self,
        loose: PerceptSet,
        motion: Motion,
        t: float,
        taken: np.ndarray,
        takers: np.ndarray,
    ) -> None:
        """One new model per foreground region from its unassociated percepts, where still.

        While the head turns, not for an object coming into view or going out of it through
        the border, nor for a part of a region ``taken`` by a model's percepts (model ``takers``
        of each) that may be of that model's object (:meth:`_part_of_taker`): an object that
        the turn brings in is cut by the border, its box grows from frame to frame faster than
        its filter follows, and the part beyond the model's box would become a second model on
        it; its foot is not yet where the memory would recognise it either. One that the turn
        takes out would leave with a model never seen whole, which the memory cannot place,
        and come back as another. It gets its model once whole, or once the head is still;
        a remembered object coming back gets its model (and id) at once when the memory
        recognises it: by where its box should be when it comes in through the border, by
        where it stands and its colour when the split cut it out of another's region (the
        remembered anchors in view take part in the split, :meth:`split_models`). With a
        pose, the head turning or not, a part of a model's object adds its colours to the
        model's (:meth:`_absorb`) instead of becoming a model of its own. A model unseen in this
        frame whose object the seed is, by where it was last seen whole and its colour, takes
        the seed rather than a new model being made (:meth:`_refind`)."""
        loose = self._recognise_pieces(loose, motion, t)
        if not len(loose):
            return
        regions, groups = np.unique(loose.regions, return_inverse=True)
        seeds = combine(groups, len(regions), loose)
        big = seeds.counts >= self.min_seed_pixels
        if not big.any():  # (a fragment too small to seed a model, as in most frames with one)
            return
        still = motion.fraction(seeds.boxes) <= self.params.max_seed_motion
        ok = still & big
        if self.turn is None:  # (each seed's region: that of its first piece)
            groups = pieces(seeds.boxes, seeds.histograms, ok)
            seeds = combine(groups, int(groups.max()) + 1, seeds)
            regions, ok = seeds.regions, ok[np.unique(groups, return_index=True)[1]]
        entering = cut = np.zeros(len(regions), bool)
        part_of = np.full(len(regions), -1)
        if self.turn is not None:
            entering = coming_into_view(seeds.boxes, self.turn, self.width, self.height)
            # (the inverse view change brings the scene in where the turn takes it out)
            cut = entering | coming_into_view(
                seeds.boxes, np.linalg.inv(self.turn), self.width, self.height
            )
        if self.pose is not None:
            turning = self.turn is not None
            part_of = self._part_of_taker(regions, seeds, taken, takers, turning)
        part_of = np.where(part_of >= 0, part_of, self._double_of(seeds, t))
        shared = part_of >= 0
        rows = np.flatnonzero(ok)
        recalled: list[Remembered | None] = [None] * len(rows)
        if self.memory is not None and self.pose is not None and len(rows):
            recalled = self.memory.recall(
                seeds.boxes[rows], seeds.histograms[rows], self.pose, entering[rows]
            )
        known = np.array([r is not None for r in recalled], bool)
        self._absorb(seeds, rows[shared[rows] & ~known], part_of)
        keep = ~(cut[rows] | shared[rows]) | known
        new = keep & ~known
        keep[new] = ~self._refind(seeds, rows[new], t)  # an unseen model's object, back
        ok[rows[~keep]] = False
        recalled = [r for r, k in zip(recalled, keep.tolist(), strict=True) if k]
        if ok.any():
            self._add(seeds.boxes[ok], seeds.histograms[ok], seeds.counts[ok], recalled, t)

    def _double_of(self, seeds: PerceptSet, t: float) -> np.ndarray:
        """For each of the ``seeds``, a model seen at ``t`` of which it would be a double
        (:meth:`_merge_doubles`), else -1: its object's, whose colours it takes instead."""
        seen = np.flatnonzero(self.last_seen == t)
        if not len(seen) or not len(seeds):
            return np.full(len(seeds), -1)
        same = _doubles(
            seeds.boxes,
            seeds.histograms,
            self.boxes[seen],
            self.histograms[seen],
            self.params.t_color,
        )
        return np.where(same.any(axis=1), seen[same.argmax(axis=1)], -1)

    def _merge_doubles(self, t: float) -> np.ndarray:
        """Which models are doubles of an older model, to be deleted: both seen at ``t`` and
        still (objects that move past one another overlap for a while), the box of one at
        least :data:`DOUBLE` inside the other's, in its colours (``t_color``) or its hue (both
        with a hue). A double is born where the split hands one object's pixels to two models
        (a face in another shade, a piece cut off by the image's border, a seed made while the
        head turned), and it lives on as long as the object, each model keeping the pixels of
        its own shade. The older model takes the double's colours, as of a percept of its
        object."""
        seen = np.flatnonzero((self.last_seen == t) & ~self.in_motion)
        double = np.zeros(len(self.ids), bool)
        if len(seen) < 2:
            return double
        boxes = self.boxes
        if not may_double(boxes, seen, DOUBLE):  # the usual frame: no colours to compare
            return double
        boxes, histograms = boxes[seen], self.histograms[seen]
        same = _doubles(boxes, histograms, boxes, histograms, self.params.t_color)
        # (order by creation, then by position: a model made in the same frame is younger
        # when it comes later)
        order = np.argsort(self.created[seen], kind="stable")
        rank = np.empty(len(seen), np.intp)
        rank[order] = np.arange(len(seen))
        younger = rank[:, None] > rank[None, :]
        pairs = same & younger
        for i in np.argsort(-rank).tolist():  # youngest first: each double goes to its oldest
            if double[seen[i]] or not pairs[i].any():
                continue
            olders = np.flatnonzero(pairs[i] & ~double[seen])
            if not len(olders):
                continue
            keeper = seen[olders[np.argmin(rank[olders])]]
            double[seen[i]] = True
            self.histograms[keeper] = _blend(
                self.histograms[keeper], self.histograms[seen[i]], self.params.alpha
            )
        return double

    def _refind(self, seeds: PerceptSet, rows: np.ndarray, t: float) -> np.ndarray:
        """Which ``seeds`` (``rows`` of them) are the objects of models unseen in this frame
        (:meth:`AnchorMemory.refind`, with a pose), or doubles of a still one's predicted box
        (:func:`_doubles`, with a pose or without); those models take them, started again at
        their boxes. (A double of an unseen model, made a model, would be deleted as a double
        as soon as both are seen, and made again whenever the older one is missed: a new
        anchor every other frame.)"""
        unseen = np.flatnonzero(self.last_seen < t)
        if not len(rows) or not len(unseen):
            return np.zeros(len(rows), bool)
        found = np.full(len(rows), -1)
        if self.memory is not None and self.pose is not None:
            found = self.memory.refind(
                seeds.boxes[rows],
                seeds.histograms[rows],
                self.pose,
                [self.ids[i] for i in unseen],
                self.histograms[unseen],
            )
        double = _doubles(
            seeds.boxes[rows],
            seeds.histograms[rows],
            self.boxes[unseen],
            self.histograms[unseen],
            self.params.t_color,
        )
        double &= ~self.in_motion[unseen][None, :]
        found = np.where(found >= 0, found, np.where(double.any(axis=1), double.argmax(axis=1), -1))
        taken = found >= 0
        models, rows = unseen[found[taken]], rows[taken]
        boxes = seeds.boxes[rows]
        self.filters.restart(models, _measurement(boxes))
        self.histograms = self.histograms.copy()  # (the snapshots handed out keep the old one)
        self.histograms[models] = _blend(
            self.histograms[models], seeds.histograms[rows], self.params.alpha
        )
        self.last_seen[models] = t
        self.pixels[models] = seeds.counts[rows]
        self.cut[models] = touches_border(boxes, self.width, self.height)
        self.away[models] = False
        return taken

    def _part_of_taker(
        self,
        regions: np.ndarray,
        seeds: PerceptSet,
        taken: np.ndarray,
        takers: np.ndarray,
        turning: bool,
    ) -> np.ndarray:
        """For each of the ``seeds`` (of ``regions``) that lies in a region ``taken`` by the
        percepts of a model (``takers``) and may be a part of that model's object, that model,
        else -1. While the head is ``turning``: in its colours (``t_color``), or overlapping its
        box at all (:data:`PART`) in its hue or without a hue to tell; the others are other
        objects that only touch it, or stand before or behind it (an object in another hue whose
        box overlaps the model's would otherwise never get its model while the head keeps
        turning). While it holds still: mostly inside its box (:data:`INSIDE`), in its hue."""
        if not len(taken):
            return np.full(len(regions), -1)
        models = self.histograms[takers]
        inside = covered(seeds.boxes, self.boxes[takers]) >= (PART if turning else INSIDE)
        part = inside & _same_hue(seeds.histograms, models)
        if turning:
            part |= colour_similarity(seeds.histograms, models) > self.params.t_color
        part &= regions[:, None] == taken[None, :]
        return np.where(part.any(axis=1), takers[part.argmax(axis=1)], -1)

    def _absorb(self, seeds: PerceptSet, rows: np.ndarray, part_of: np.ndarray) -> None:
        """The models' histograms take in the colours of the ``seeds`` (``rows`` of them) that
        are parts of their objects (``part_of``), as of a percept: a face in another shade that
        a model never saw would otherwise stay out of its colours for good. (In place: a part
        has a taker, so :meth:`update` copied the histograms in this frame already.)"""
        for i in rows.tolist():
            model = part_of[i]
            self.histograms[model] = _blend(
                self.histograms[model], seeds.histograms[i], self.params.alpha
            )

    def _recognise_pieces(self, loose: PerceptSet, motion: Motion, t: float) -> PerceptSet:
        """Give the remembered objects among the pieces the colour split cut from a region (a
        region of several loose percepts) their models back, each piece apart from the rest of
        its region (combined with it, it would be one new model of two objects): a piece that
        is still, clear of the border and recognised by the memory. The other loose percepts."""
        if self.memory is None or self.pose is None or not self.memory.remembered:
            return loose
        _, groups, sizes = np.unique(loose.regions, return_inverse=True, return_counts=True)
        candidate = (sizes[groups] > 1) & (loose.counts >= self.min_seed_pixels)
        candidate &= ~touches_border(loose.boxes, self.width, self.height)
        candidate &= motion.fraction(loose.boxes) <= self.params.max_seed_motion
        rows = np.flatnonzero(candidate)
        if not len(rows):
            return loose
        recalled = self.memory.recall(loose.boxes[rows], loose.histograms[rows], self.pose)
        found = [k for k, r in enumerate(recalled) if r is not None]
        if not found:
            return loose
        chosen = rows[found]
        self._add(
            loose.boxes[chosen],
            loose.histograms[chosen],
            loose.counts[chosen],
            [recalled[k] for k in found],
            t,
        )
        rest = np.ones(len(loose), bool)
        rest[chosen] = False
        return loose.select(rest)

    def _add(
        self,
        boxes: np.ndarray,
        histograms: np.ndarray,
        counts: np.ndarray,
        recalled: list[Remembered | None],
        t: float,
    ) -> None:
        """New models of ``boxes``, ``histograms`` (copied) and pixel ``counts`` seen at ``t``:
        those ``recalled`` from the memory with their old ids and models, the others new."""
        n = len(boxes)
        histograms = histograms.copy()
        created = np.full(n, t)
        ids: list[str] = []
        for k, old in enumerate(recalled):
            if old is None:
                ids.append(f"o{self._next}")
                self._next += 1
            else:  # an object come back: its old id, and its model as a model seen again
                ids.append(old.id)
                created[k] = old.created
                histograms[k] = _blend(old.histograms, histograms[k], self.params.alpha)
        self.filters.add(_measurement(boxes))
        self.histograms = np.concatenate([self.histograms, histograms])
        self.ids += ids
        self.created = np.concatenate([self.created, created])
        self.last_seen = np.concatenate([self.last_seen, np.full(n, t)])
        self.pixels = np.concatenate([self.pixels, counts])
        self.in_motion = np.concatenate([self.in_motion, np.zeros(n, bool)])
        self.whole = np.concatenate([self.whole, np.zeros(n, bool)])
        self.cut = np.concatenate([self.cut, touches_border(boxes, self.width, self.height)])
        self.away = np.concatenate([self.away, np.zeros(n, bool)])

    def _keep(self, rows: np.ndarray) -> None:
        self.filters.keep(rows)
        self.histograms = self.histograms[rows]
        self.ids = [i for i, k in zip(self.ids, rows, strict=True) if k]
        self.created, self.last_seen = self.created[rows], self.last_seen[rows]
        self.pixels, self.in_motion = self.pixels[rows], self.in_motion[rows]
        self.whole, self.cut, self.away = self.whole[rows], self.cut[rows], self.away[rows]


def coming_into_view(boxes: np.ndarray, H: np.ndarray, width: int, height: int) -> np.ndarray:
    """Which boxes (n, 4) of a ``width`` x ``height`` image touch a border through which the
    view's change ``H`` (3x3, the previous frame's pixels to this one's) brings the scene in:
    the right border when the image's content moves left by more than a pixel at the box's
    middle, and so on for the other three."""
    middle = np.column_stack([boxes[:, :2] + boxes[:, 2:] / 2, np.ones(len(boxes))])
    before = middle @ np.linalg.inv(H).T
    flow = middle[:, :2] - before[:, :2] / before[:, 2:3]
    left, top = boxes[:, 0], boxes[:, 1]
    right, bottom = left + boxes[:, 2], top + boxes[:, 3]
    return (
        ((left < 1) & (flow[:, 0] > 1))
        | ((right > width - 1) & (flow[:, 0] < -1))
        | ((top < 1) & (flow[:, 1] > 1))
        | ((bottom > height - 1) & (flow[:, 1] < -1))
    )


def _blend(model: np.ndarray, seen: np.ndarray, alpha: float) -> np.ndarray:
    """A model's histograms (..., factors, bins) updated with those ``seen`` of its object, as
    the correction after the association updates them (:func:`~percept.perception.tracking.
    anchors_kernels.blend`)."""
    shape = model.shape[-2:]
    rows = [np.ascontiguousarray(h, dtype=float).reshape(-1, *shape) for h in (model, seen)]
    return blend(rows[0], rows[1], float(alpha)).reshape(model.shape)


def _same_hue(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)): whether the colours of histograms ``a`` (k, factors, bins) and ``b``
    (n, factors, bins) may be shades of one colour: hues within :data:`SAME_HUE`, or one of
    them without a hue."""
    close, grey = _hues(a, b)
    return grey | close


def _hues(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(len(a), len(b)) each: whether the hues of histograms ``a`` and ``b`` are within
    :data:`SAME_HUE`, and whether one of the two has no hue to tell (chroma under
    :data:`MIN_CHROMA`)."""
    hue_a, chroma_a = hue(a)
    hue_b, chroma_b = hue(b)
    close = np.abs(wrap(hue_a[:, None] - hue_b[None, :])) < SAME_HUE
    grey = (chroma_a[:, None] < MIN_CHROMA) | (chroma_b[None, :] < MIN_CHROMA)
    return close, grey


def _doubles(
    boxes_a: np.ndarray, hist_a: np.ndarray, boxes_b: np.ndarray, hist_b: np.ndarray, t_color: float
) -> np.ndarray:
    """(len(a), len(b)): whether a model or seed of box and histograms ``a`` and one of ``b``
    are one object's (:data:`DOUBLE`): the box of one at least that much inside the other's, in
    its colours (``s_color`` above ``t_color``) or its hue (both with a hue to tell)."""
    inside_ab = covered(boxes_a, boxes_b)
    inside_ba = covered(boxes_b, boxes_a).T
    overlap = np.maximum(inside_ab, inside_ba) >= DOUBLE
    close, grey = _hues(hist_a, hist_b)
    same = (close & ~grey) | (colour_similarity(hist_a, hist_b) > t_color)
    return overlap & same


def pieces(boxes: np.ndarray, histograms: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """Group (0..k-1, in order of first member) of each of ``boxes`` (n, 4) with
    ``histograms`` (n, factors, bins): boxes apart by at most :data:`PIECE_GAP` of the smaller one's
    size in both directions, in one hue (both with a hue, within :data:`SAME_HUE`) or both
    without a hue, are one group, and so is every chain of such pairs, among those that are
    ``seeds`` (n,) bool: each would be an anchor of its own. The others stay alone: bits of
    foreground too small or moving to be seeds, taken together, would be seeds of nothing. Not
    hue against no hue: a grey object beside a coloured one is two objects."""
    n = len(boxes)
    if n < 2:
        return np.zeros(n, np.intp)
    left, top = boxes[:, 0], boxes[:, 1]
    right, bottom = left + boxes[:, 2], top + boxes[:, 3]
    gap_x = np.maximum(left[:, None], left[None, :]) - np.minimum(right[:, None], right[None, :])
    gap_y = np.maximum(top[:, None], top[None, :]) - np.minimum(bottom[:, None], bottom[None, :])
    width = np.minimum(boxes[:, None, 2], boxes[None, :, 2])
    height = np.minimum(boxes[:, None, 3], boxes[None, :, 3])
    near = (gap_x <= PIECE_GAP * width) & (gap_y <= PIECE_GAP * height)
    close, _ = _hues(histograms, histograms)
    _, chroma = hue(histograms)
    hued = chroma >= MIN_CHROMA
    one_colour = np.where(hued[:, None] & hued[None, :], close, ~hued[:, None] & ~hued[None, :])
    linked = near & one_colour & seeds[:, None] & seeds[None, :]
    groups = np.full(n, -1, np.intp)
    k = 0
    for i in range(n):  # connected components of the links, numbered by first member
        if groups[i] >= 0:
            continue
        stack = [i]
        groups[i] = k
        while stack:
            j = stack.pop()
            for other in np.flatnonzero(linked[j] & (groups < 0)).tolist():
                groups[other] = k
                stack.append(other)
        k += 1
    return groups


def _measurement(boxes: np.ndarray) -> np.ndarray:
    """(x, y, w, h) with x, y the centre, from (left, top, width, height)."""
    return np.concatenate([boxes[:, :2] + boxes[:, 2:] / 2, boxes[:, 2:]], axis=1)
