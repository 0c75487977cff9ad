"""Object permanence: anchors remembered while out of view or hidden behind a nearer object.

With the camera model and each frame's camera pose, :class:`AnchorMemory` knows where every
anchor stands on the ground: where the ray through the middle of its box's lower edge (the foot
of an object standing there) meets the ground plane, taken only from frames in which the anchor
was seen *whole*, its percepts clear of the image's border and its box clear of the boxes of
nearer anchors seen in the same frame (or touching them by a corner, :data:`TOUCHING`), so that a
box cut by the border or by a nearer object does not shift it. In an image of objects on the
ground the nearer of two has the lower foot, which is what "nearer" means here. A frame in which
an anchor is seen clear of the border but not whole, with less than ``out_of_sight`` of its box
under nearer ones, gives a rougher position (its foot may be hidden): without it, an object that
stands partly behind another from the start could not be remembered at all, and one that moves
while partly hidden would be remembered where it was when last seen whole. An anchor seen only
ever cut by the border (an object so near that the image's bottom cuts its foot off, say) has
no place on the ground; it is remembered by a *glimpse* instead: the corners of its fullest box
as directions from the camera, which give where its box should be in any later view, and it is
recognised by its box, as an object coming in through the border is.

An anchor unseen for ``max_absence`` seconds is deleted as without a pose, unless it is out of
sight then: less than ``out_of_sight`` of its box inside the image, or at least that much of it
under the box of a nearer anchor seen in the frame. Then it leaves the tracker for the memory
with its id, histograms and ground position, and stays in the world model, not visible, for
``memory`` seconds (counted from when it was last seen); each frame its box is where its ground
position and its size then (scaled by the change of distance) fall in the current view. A new
object whose foot is within ``reacquire_distance`` of a remembered place and whose colour passes
``t_color`` takes the remembered id back (the nearest one first), also when it was moved a little
meanwhile. An anchor still in the tracker but unseen (its box carried off its object, say, by
a warp with a pose that lagged a head turn) takes a new object back the same way
(:meth:`AnchorMemory.refind`), rather than a second anchor being made on one object; and a
remembered anchor is forgotten once an anchor in its colour is seen within
``reacquire_distance`` of its place: its object was anchored again before it left the tracker
(:meth:`AnchorMemory.forget_doubles`). A remembered anchor whose place is in view, not hidden,
and still (no motion there) for ``max_absence`` seconds without that happening was taken away:
it is forgotten.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.ground import ground_points
from percept.kinematics.pose import CameraPose
from percept.perception.params import AnchorParams
from percept.perception.tracking.association_kernels import colour_similarity
from percept.perception.tracking.motion import Motion
from percept.perception.tracking.permanence import memory_kernels as kernels

TOUCHING = 0.02
"""A share of a box under a nearer anchor's box below which the two boxes only touch (a corner
a pixel or two deep, within their edges' noise): the box still counts as seen whole."""


def feet_on_ground(
    camera: CameraModel, pose: CameraPose, boxes: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Ground positions (n, 2) of the middles of the lower edges of ``boxes`` (n, 4: left, top,
    width, height), and which of them meet the ground (n,) bool."""
    if len(boxes) == 0:  # OpenCV's undistortion returns no array for no points
        return np.zeros((0, 2)), np.zeros(0, bool)
    return ground_points(pose, camera.pixel_rays(kernels.feet(_boxes(boxes))))


def ground_pixels(camera: CameraModel, pose: CameraPose, xy: np.ndarray) -> np.ndarray:
    """Pixels (n, 2) of ground points ``xy`` (n, 2) seen from ``pose``; NaN behind the camera."""
    ground = np.column_stack([xy, np.zeros(len(xy))])
    return camera.project((ground - pose.t) @ pose.R)


def touches_border(boxes: np.ndarray, width: int, height: int) -> np.ndarray:
    """Which boxes (n, 4) reach the outermost pixels of a ``width`` x ``height`` image (the
    object may go on beyond it; compiled:
    :func:`percept.perception.compiled.boxes_kernels.on_border`)."""
    return kernels.touches_border(_boxes(boxes), width, height)


def inside_fraction(boxes: np.ndarray, width: int, height: int) -> np.ndarray:
    """Fraction (n,) of each box's area inside a ``width`` x ``height`` image."""
    return kernels.inside_fraction(_boxes(boxes), width, height)


def hidden_fraction(boxes: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """Fraction (n,) of each box under the box of the nearer (lower foot) anchors ``seen``
    (k, 4): the largest such share of one box."""
    return kernels.hidden_fraction(_boxes(boxes), _boxes(seen))


def covered(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)): the share of each box of ``a`` that each box of ``b`` covers."""
    return kernels.covered(_boxes(a), _boxes(b))


def _boxes(boxes: np.ndarray) -> np.ndarray:
    """Boxes as the kernels take them (one signature each): contiguous float64 (n, 4)."""
    return np.ascontiguousarray(boxes, dtype=float).reshape(-1, 4)


def _centre(pose: CameraPose) -> np.ndarray:
    """The camera's centre as the kernels take it (one signature each): contiguous float64."""
    return np.ascontiguousarray(pose.t, dtype=float)


@dataclass(frozen=True)
class Sighting:
    """Where an anchor stood when it was last seen whole."""

    ground: np.ndarray
    """(2,) its foot on the ground, metres."""
    size: tuple[float, float]
    """Its box's width and height then, pixels."""
    reach: float
    """Metres from the camera to its foot then (the box's size scales with its inverse)."""


def glimpse_of(camera: CameraModel, pose: CameraPose, box: np.ndarray) -> np.ndarray:
    """The corners of ``box`` (left, top, width, height) seen from ``pose``, as directions
    (4, 3) in the ground frame: where an object seen only cut by the image's border was, which
    its foot cannot say."""
    left, top, width, height = box
    corners = np.array(
        [[left, top], [left + width, top], [left + width, top + height], [left, top + height]]
    )
    return camera.pixel_rays(corners) @ pose.R.T


def glimpsed_box(camera: CameraModel, pose: CameraPose, glimpse: np.ndarray) -> np.ndarray:
    """The box (4,) where the directions of a ``glimpse`` fall in the view from ``pose`` (NaN
    when one lies behind the camera); the camera's shift as the head turns is left out."""
    corners = camera.project(glimpse @ pose.R)
    low, high = corners.min(axis=0), corners.max(axis=0)
    return np.concatenate([low, high - low])


def _places_of(kept: list[Remembered], missing: float = np.inf) -> np.ndarray:
    """(k, 2): where the remembered anchors ``kept`` stood, ``missing`` for those that have no
    place on the ground (only glimpsed)."""
    return np.array([r.sighting.ground if r.sighting else (missing, missing) for r in kept])


@dataclass
class Remembered:
    """An anchor out of sight: what the tracker knew of it when it went."""

    id: str
    sighting: Sighting | None
    """Where it stood when last seen whole (None: never, only cut by the border: ``glimpse``)."""
    histograms: np.ndarray
    created: float
    last_seen: float
    pixels: int
    bbox: tuple[float, float, float, float]
    """Where it should be in the current view (its last box while that cannot be said)."""
    empty_since: float | None = None
    """Since when its place has been in view, not hidden, still and empty."""
    glimpse: np.ndarray | None = None
    """Without a ``sighting``: its box's corners when last seen, cut by the border
    (:func:`glimpse_of`)."""


class AnchorMemory:
    """The sightings of the tracker's anchors and the anchors out of sight."""

    def __init__(self, params: AnchorParams, camera: CameraModel, width: int, height: int) -> None:
        self.params = params
        self.camera = camera
        self.width, self.height = width, height
        self.sightings: dict[str, Sighting] = {}
        self.glimpses: dict[str, np.ndarray] = {}
        """Of the anchors never seen but cut by the image's border: :func:`glimpse_of`."""
        self.remembered: dict[str, Remembered] = {}

    def follow(
        self,
        ids: list[str],
        boxes: np.ndarray,
        seen: np.ndarray,
        cut: np.ndarray,
        pose: CameraPose,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Note the ground positions of the tracker's anchors (``ids``, their ``boxes``, which
        were ``seen`` in this frame and which of those had percepts ``cut`` by the border) seen
        whole; which were seen whole, and which are out of sight (unseen, out of view or hidden,
        with a sighting to remember them by)."""
        whole, rough, glimpsed, away = kernels.sight(
            _boxes(boxes), seen, cut, self.width, self.height, TOUCHING, self.params.out_of_sight
        )
        rows = np.flatnonzero(whole | rough)
        xy, valid = feet_on_ground(self.camera, pose, boxes[rows])
        reach = kernels.reaches(xy, _centre(pose))
        sizes = boxes[rows, 2:4].tolist()
        noted = zip(rows.tolist(), xy, valid.tolist(), reach.tolist(), sizes, strict=True)
        for i, g, ok, r, (width, height) in noted:
            if ok:
                self.sightings[ids[i]] = Sighting(g, (width, height), r)
        for i in np.flatnonzero(glimpsed).tolist():
            if ids[i] not in self.sightings and self._larger(ids[i], boxes[i], pose):
                self.glimpses[ids[i]] = glimpse_of(self.camera, pose, boxes[i])
        known = np.array([i in self.sightings or i in self.glimpses for i in ids], bool)
        return whole, ~seen & known & away

    def _larger(self, anchor_id: str, box: np.ndarray, pose: CameraPose) -> bool:
        """Whether ``box`` shows more of an anchor's object than its glimpse, brought into the
        view from ``pose``, does: the glimpse kept is the fullest view, not the sliver the
        border leaves of the object as it goes out of view."""
        glimpse = self.glimpses.get(anchor_id)
        if glimpse is None:
            return True
        before = glimpsed_box(self.camera, pose, glimpse)
        # "not smaller", so that a glimpse now behind the camera (a NaN box) gives way to any box
        return not bool(box[2] * box[3] < before[2] * before[3])

    def keep(self, anchor: Remembered) -> None:
        """Remember an anchor that went out of sight (its sighting is the last one noted)."""
        self.remembered[anchor.id] = anchor

    def forget_sightings(self, alive: list[str]) -> None:
        """Drop the sightings of anchors neither alive in the tracker nor remembered."""
        keep = set(alive) | self.remembered.keys()
        if keep.issuperset(self.sightings) and keep.issuperset(self.glimpses):
            return  # the usual frame: no anchor left the tracker or the memory
        self.sightings = {i: s for i, s in self.sightings.items() if i in keep}
        self.glimpses = {i: g for i, g in self.glimpses.items() if i in keep}

    def recall(
        self,
        boxes: np.ndarray,
        histograms: np.ndarray,
        pose: CameraPose,
        cut: np.ndarray | None = None,
    ) -> list[Remembered | None]:
        """For each new object (its box and histograms), the remembered anchor it is, or None:
        the nearest on the ground within ``reacquire_distance`` whose colour passes ``t_color``,
        each remembered anchor to one object. The anchors recalled are no longer remembered.

        An object ``cut`` (n,) by the image's border, coming into view, has no foot to go by,
        and an anchor only ever seen cut by it has no place on the ground: the object is such
        an anchor of its colour when at least ``out_of_sight`` of its box lies in the box where
        that anchor should be (:meth:`review`), nearer the more it does."""
        out: list[Remembered | None] = [None] * len(boxes)
        if not self.remembered or len(boxes) == 0:
            return out
        p = self.params
        kept = list(self.remembered.values())
        xy, valid = feet_on_ground(self.camera, pose, boxes)
        placed = np.array([r.sighting is not None for r in kept])
        distance = np.linalg.norm(xy[:, None, :] - _places_of(kept)[None, :, :], axis=2)
        by_box = ~placed[None, :] if cut is None else cut[:, None] | ~placed[None, :]
        if by_box.any():
            inside = covered(boxes, np.array([r.bbox for r in kept]))
            near = np.where(inside >= p.out_of_sight, 1 - inside, np.inf) * p.reacquire_distance
            distance = np.where(by_box, near, distance)
        models = np.array([r.histograms for r in kept])
        for i, j in self._pairs(distance, valid[:, None] | by_box, histograms, models):
            out[i] = self.remembered.pop(kept[j].id)
        return out

    def refind(
        self,
        boxes: np.ndarray,
        histograms: np.ndarray,
        pose: CameraPose,
        ids: list[str],
        models: np.ndarray,
    ) -> np.ndarray:
        """For each new object (its box and histograms, its foot clear of the border), which of
        the tracker's anchors ``ids`` (their histograms ``models``), unseen in this frame, it is
        (an index into ``ids``), or -1: by where each was last seen whole and its colour, as
        :meth:`recall` finds a remembered one. An anchor that lost its object (its filter's
        rates carried its box off while the joint angles lagged a head turn, say) takes it back
        instead of a second anchor being made on it."""
        out = np.full(len(boxes), -1)
        known = [k for k, i in enumerate(ids) if i in self.sightings]
        if not known or len(boxes) == 0:
            return out
        xy, valid = feet_on_ground(self.camera, pose, boxes)
        places = np.array([self.sightings[ids[k]].ground for k in known])
        distance = np.linalg.norm(xy[:, None, :] - places[None, :, :], axis=2)
        for i, j in self._pairs(distance, valid[:, None], histograms, models[known]):
            out[i] = known[j]
        return out

    def _pairs(
        self, distance: np.ndarray, valid: np.ndarray, histograms: np.ndarray, models: np.ndarray
    ) -> list[tuple[int, int]]:
        """Objects (rows of ``distance``, metres from each object to each place; ``valid``
        (n, 1 or k): the distances that count) paired one to one with places (columns, the
        anchors of histograms ``models``) within ``reacquire_distance`` whose colour passes
        ``t_color``, the nearest first."""
        distance = np.where(self._fits(distance, valid, histograms, models), distance, np.inf)
        pairs = []
        while np.isfinite(distance).any():
            i, j = np.unravel_index(np.argmin(distance), distance.shape)
            pairs.append((int(i), int(j)))
            distance[i, :] = np.inf
            distance[:, j] = np.inf
        return pairs

    def _fits(
        self, distance: np.ndarray, valid: np.ndarray, histograms: np.ndarray, models: np.ndarray
    ) -> np.ndarray:
        """(n, k): which objects (``distance`` rows, ``valid``, ``histograms``) may be which
        anchors (columns, ``models``): within ``reacquire_distance``, colour past ``t_color``."""
        fits = valid & (distance <= self.params.reacquire_distance)
        return fits & (colour_similarity(histograms, models) > self.params.t_color)

    def forget_doubles(self, ids: list[str], histograms: np.ndarray) -> None:
        """Forget the remembered anchors that an anchor seen in this frame (``ids``, with
        ``histograms``) stands in for: it was last seen whole within ``reacquire_distance`` of
        one's place and passes its colour. That is the remembered one's object, anchored again
        while it was remembered (a new anchor made on it before the old one left the tracker);
        kept, the remembered anchor would come back as a second anchor on it once the colour
        split cut a piece off the object."""
        here = [k for k, i in enumerate(ids) if i in self.sightings]
        if not self.remembered or not here:
            return
        kept = list(self.remembered.values())
        seen = np.array([self.sightings[ids[k]].ground for k in here])
        distance = np.linalg.norm(_places_of(kept)[:, None, :] - seen[None, :, :], axis=2)
        models = np.array([r.histograms for r in kept])
        doubles = self._fits(distance, np.ones((len(kept), 1), bool), models, histograms[here])
        for k in np.flatnonzero(doubles.any(axis=1)).tolist():
            del self.remembered[kept[k].id]

    def _places(self, kept: list[Remembered], pose: CameraPose) -> tuple[np.ndarray, np.ndarray]:
        """Where the remembered anchors ``kept`` should be in the view from ``pose`` (their
        last boxes where that cannot be said), and how much of each box is inside the image."""
        places = _places_of(kept, np.nan)
        feet = ground_pixels(self.camera, pose, places)
        reach = kernels.reaches(places, _centre(pose))
        sizes = np.array([r.sighting.size if r.sighting else (np.nan,) * 2 for r in kept])
        then = np.array([r.sighting.reach if r.sighting else np.nan for r in kept])
        sizes *= then[:, None] / reach[:, None]
        boxes = np.column_stack(
            [feet[:, 0] + 0.5 - sizes[:, 0] / 2, feet[:, 1] + 0.5 - sizes[:, 1], sizes]
        )
        for k, r in enumerate(kept):
            if r.sighting is None and r.glimpse is not None:
                boxes[k] = glimpsed_box(self.camera, pose, r.glimpse)
        known = np.isfinite(boxes).all(axis=1)
        boxes = np.where(known[:, None], boxes, [r.bbox for r in kept])
        inside = np.where(known, inside_fraction(boxes, self.width, self.height), 0.0)
        return boxes, inside

    def in_view(self, pose: CameraPose) -> tuple[list[Remembered], np.ndarray]:
        """The remembered anchors whose place is in the view from ``pose`` (at least
        ``out_of_sight`` of the box where each should be inside the image), and those boxes."""
        kept = list(self.remembered.values())
        if not kept:
            return [], np.zeros((0, 4))
        boxes, inside = self._places(kept, pose)
        back = inside >= self.params.out_of_sight
        return [r for r, b in zip(kept, back.tolist(), strict=True) if b], boxes[back]

    def review(self, pose: CameraPose, t: float, seen: np.ndarray, motion: Motion) -> None:
        """Bring the remembered anchors into the view from ``pose`` at time ``t`` (``seen``: the
        boxes of the anchors seen in it); forget those remembered longer than ``memory`` and
        those whose place has been in view, not hidden, still and empty for ``max_absence``."""
        p = self.params
        for r in list(self.remembered.values()):
            if t - r.last_seen > p.memory:
                del self.remembered[r.id]
        if not self.remembered:
            return
        kept = list(self.remembered.values())
        boxes, inside = self._places(kept, pose)
        hidden = hidden_fraction(boxes, seen)
        still = motion.fraction(boxes) == 0
        empty = (inside >= p.out_of_sight) & (hidden < p.out_of_sight) & still
        for r, box, is_empty in zip(kept, boxes.tolist(), empty.tolist(), strict=True):
            r.bbox = tuple(box)
            if not is_empty:
                r.empty_since = None
            elif r.empty_since is None:
                r.empty_since = t
            elif t - r.empty_since > p.max_absence:
                del self.remembered[r.id]
