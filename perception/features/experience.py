"""Sensory experiences: the seven features of an object (chapter 5.2.3, SPEC §4.5).

The chapter's construction (``model = "chapter"``): ``x, y`` is where the middle of the bounding
box's lower edge meets the ground (metres, ground frame); ``width`` the distance between the ground
points of the lower-left and lower-right corners; ``height`` where the ray through the middle of
the upper edge meets the vertical plane through the object's position that faces the camera.
``luminance``, ``green_red``, ``yellow_blue``: means of the object's Y, Cr and Cb histograms on the
0..255 scale.

The lower edge of a solid object is its front, and a camera looking down sees the far rim of its
top, so the chapter's position lies half an object short of its centre and its height is too large
by up to the object's depth (50 % for a cube seen from 30 degrees above); away from the image
centre the lean of vertical edges widens the box. ``model = "cylinder"`` starts from the chapter's
construction moved to the footprint's centre and then fits the upright cylinder whose image has
exactly the bounding box (:mod:`percept.perception.features.footprint`): x, y are its centre, width
its diameter, height its height. That reads objects that narrow upwards (cones, balls, toys) 15-30 %
too low. ``model = "solid"`` (the default, chosen by measurement, README "Kinematics and sensory
experiences") also uses the silhouette's pixel count to choose among a ball, that cylinder and a
frustum (down to a cone) with the same bounding box
(:func:`percept.perception.features.footprint.fit_solid`); without a pixel count it is the cylinder
model. Colour is the same in all models.

An object whose lower edge does not meet the ground (at or above the horizon) keeps its colour
features but has ``on_ground`` False and ``x, y, width, height`` None: there is no honest number
for them. ``on_ground`` True guarantees all four are numbers.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING, Literal, NamedTuple

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.ground import MAX_DISTANCE, ground_points, height_at
from percept.kinematics.pose import CameraPose, same_pose
from percept.perception.colour import histogram_means
from percept.perception.features.footprint import Solid, fit_cylinder, fit_solid, refit_solid

if TYPE_CHECKING:  # (anchors read colours, which read this module's histogram means)
    from percept.perception.tracking.anchors import Anchor

FEATURES = ("x", "y", "width", "height", "luminance", "green_red", "yellow_blue")
SPATIAL = FEATURES[:4]

# A silhouette whose pixel count changed by at most this fraction (and at least one pixel) has
# the same spatial features (:class:`SensoryMemory`): a count that flickers by a few pixels at
# the edges moves the solid model's fit by far less than a millimetre, and refitting it costs
# a millisecond per anchor.
SAME_PIXELS = 0.002


@dataclass(frozen=True)
class FeatureSettings:
    """How sensory experiences are computed (the experiment's ``[features]`` table)."""

    model: Literal["solid", "cylinder", "chapter"] = field(
        default="solid",
        metadata={
            "doc": "solid: the ball, cylinder or frustum whose image has the bounding box and "
            "the pixel count (measured best); cylinder: the upright cylinder whose image has the "
            "bounding box (position at its centre); chapter: the chapter's construction"
        },
    )
    max_distance: float = field(
        default=MAX_DISTANCE,
        metadata={
            "min": 0.1,
            "max": 1000.0,
            "doc": "metres: a lower edge meeting the ground farther is off it",
        },
    )
    max_object_height: float = field(
        default=0.6,
        metadata={
            "min": 0.01,
            "max": 100.0,
            "doc": "metres: a region standing taller on the ground is an agent (a person), "
            "kept out of the world model's objects",
        },
    )
    shape_every: int = field(
        default=15,
        metadata={
            "min": 1,
            "max": 100000,
            "doc": "solid model, frame after frame (the daemon): an anchor's shape is chosen "
            "again after this many frames and only fitted again in between (choosing costs "
            "about three times as much); 1 chooses in every frame",
        },
    )


@dataclass(frozen=True)
class SensoryExperience:
    """The seven features of one object (metres; colour on 0..255).

    The spatial four are None exactly when ``on_ground`` is False.
    """

    x: float | None
    y: float | None
    width: float | None
    height: float | None
    luminance: float
    green_red: float
    yellow_blue: float
    on_ground: bool

    def __post_init__(self) -> None:
        known = [getattr(self, name) is not None for name in SPATIAL]
        if all(known) != self.on_ground or any(known) != self.on_ground:
            raise ValueError("x, y, width and height are numbers exactly when on_ground")

    def features(self) -> dict[str, float | None]:
        """The seven features by name (None where unknown), JSON-able."""
        return {name: getattr(self, name) for name in FEATURES}

    def as_dict(self) -> dict[str, float | bool | None]:
        return asdict(self)


def bbox_edge_pixels(bbox: tuple[float, float, float, float]) -> np.ndarray:
    """Pixel coordinates (4, 2) of the lower-edge middle, lower-left corner, lower-right corner
    and upper-edge middle of a box ``(left, top, width, height)`` of whole pixels.

    The box covers pixel centres ``left .. left + width - 1``; its outer edges are half a pixel
    further out (OpenCV puts pixel centres on integers).
    """
    left, top, w, h = (float(v) for v in bbox)
    x0, x1 = left - 0.5, left + w - 0.5
    y0, y1 = top - 0.5, top + h - 0.5
    xm = (x0 + x1) / 2
    return np.array([[xm, y1], [x0, y1], [x1, y1], [xm, y0]])


def sensory_experience(
    bbox: tuple[float, float, float, float],
    histograms: np.ndarray,
    camera: CameraModel,
    pose: CameraPose,
    settings: FeatureSettings = FeatureSettings(),
    *,
    pixels: int | None = None,
) -> SensoryExperience:
    """The sensory experience of an object with bounding box ``bbox`` (left, top, width, height
    in pixels) and normalised Y/Cr/Cb histograms (3, m), seen with ``camera`` from ``pose``.

    ``pixels``: how many pixels the object covers (its silhouette, inside ``bbox``), for the
    solid model; without it, or when it cannot be (none, or more than the box holds), the solid
    model is the cylinder model.
    """
    return _experience(bbox, histograms, camera, pose, settings, pixels, None)[0]


class _Fit(NamedTuple):
    """What one object's features were fitted to in a frame, the start of its next fit."""

    cylinder: tuple[float, float, float, float] | None
    solid: Solid | None
    """The solid model's choice (None: none was made), and ``decided`` the frame it was made."""
    decided: int = 0


def _experience(
    bbox: tuple[float, float, float, float],
    histograms: np.ndarray,
    camera: CameraModel,
    pose: CameraPose,
    settings: FeatureSettings,
    pixels: int | None,
    last: _Fit | None,
    frame: int = 0,
) -> tuple[SensoryExperience, _Fit]:
    """:func:`sensory_experience`, started from the object's ``last`` fit when there is one: its
    cylinder is the start of this one, and its solid's shape is kept (only fitted again) for
    ``settings.shape_every`` frames after ``last.decided``."""
    luminance, green_red, yellow_blue = (float(v) for v in histogram_means(histograms))
    off_ground = SensoryExperience(
        None, None, None, None, luminance, green_red, yellow_blue, on_ground=False
    )
    nothing = _Fit(None, None)
    marks = bbox_edge_pixels(bbox)
    rays = camera.pixel_rays(marks)
    xy, valid = ground_points(pose, rays[:3], settings.max_distance)
    if not valid.all():
        return off_ground, nothing
    front, width = xy[0], float(np.linalg.norm(xy[2] - xy[1]))
    position, height = front, height_at(pose, rays[3], front)
    sight = front - pose.t[:2]
    reach = float(np.linalg.norm(sight))
    fit = nothing
    if settings.model != "chapter" and reach > 1e-9:  # else straight down: no line of sight
        # Start from the footprint's centre and the top's far rim (or the last fit), then fit.
        sight /= reach
        position = front + sight * (width / 2)
        far = height_at(pose, rays[3], front + sight * width)
        if far is not None and far < pose.t[2]:
            height = far
        if height is not None:
            guess = (*position, width, height)
            fitted = _fitted(camera, pose, bbox, marks, guess, pixels, last, frame, settings)
            if fitted is not None:
                fit, (x, y, width, height) = fitted
                position = np.array([x, y])
    if height is None:
        return off_ground, nothing
    experience = SensoryExperience(
        x=float(position[0]),
        y=float(position[1]),
        width=width,
        height=height,
        luminance=luminance,
        green_red=green_red,
        yellow_blue=yellow_blue,
        on_ground=True,
    )
    return experience, fit


def _fitted(
    camera: CameraModel,
    pose: CameraPose,
    bbox: tuple[float, float, float, float],
    marks: np.ndarray,
    guess: tuple[float, float, float, float],
    pixels: int | None,
    last: _Fit | None,
    frame: int,
    settings: FeatureSettings,
) -> tuple[_Fit, tuple[float, float, float, float]] | None:
    """The cylinder fitted to ``bbox`` (its edge pixels ``marks``) from ``guess`` or the
    ``last`` fit, then for the solid model the solid fitted to it and the silhouette's
    ``pixels``: the fit and the (x, y, width, height) of the model fitted last. None when the
    cylinder fit fails."""
    edges = (marks[1, 0], marks[2, 0], marks[3, 1], marks[0, 1])
    start = guess if last is None or last.cylinder is None else last.cylinder
    cylinder = fit_cylinder(camera, pose, edges, start)
    if cylinder is None:
        return None
    if settings.model != "solid" or pixels is None or not _usable(pixels, bbox):
        return _Fit(cylinder, None), cylinder
    solid, decided = _solid_fit(
        camera, pose, edges, pixels, cylinder, last, frame, settings.shape_every
    )
    return _Fit(cylinder, solid, decided), (solid.x, solid.y, solid.width, solid.height)


def _solid_fit(
    camera: CameraModel,
    pose: CameraPose,
    edges: tuple[float, float, float, float],
    pixels: int,
    cylinder: tuple[float, float, float, float],
    last: _Fit | None,
    frame: int,
    every: int,
) -> tuple[Solid, int]:
    """The solid model's fit in ``frame`` and the frame its shape was chosen: ``last``'s shape
    fitted again while its choice is younger than ``every`` frames, else a shape chosen afresh."""
    if last is not None and last.solid is not None and frame - last.decided < every:
        return refit_solid(camera, pose, edges, pixels, cylinder, last.solid), last.decided
    return fit_solid(camera, pose, edges, pixels, cylinder), frame


class _Sighting(NamedTuple):
    """What an anchor's spatial features were computed from in a frame, and those features."""

    bbox: tuple[float, float, float, float]
    pixels: int | None
    pose: CameraPose
    experience: SensoryExperience


def _same_sighting(
    last: _Sighting,
    bbox: tuple[float, float, float, float],
    pixels: int | None,
    pose: CameraPose,
    count_read: bool = True,
) -> bool:
    """Whether an anchor seen in box ``bbox`` with ``pixels`` from ``pose`` has the spatial
    features of its ``last`` sighting: the same box and camera pose to the bit, and a pixel
    count (used by the solid model only) within :data:`SAME_PIXELS` of the last one, or none
    both times. ``count_read`` False: this frame's fit would not read the count
    (:meth:`SensoryMemory._reads_count`): then any count will do that the solid model can use
    exactly when it could use the last one."""
    if last.bbox != tuple(bbox) or not same_pose(last.pose, pose):
        return False
    if last.pixels is None or pixels is None:
        return last.pixels is pixels
    if not count_read:
        return _usable(pixels, bbox) == _usable(last.pixels, bbox)
    return _same_count(last.pixels, pixels)


def _same_count(last: int, pixels: int) -> bool:
    """A pixel count within :data:`SAME_PIXELS` of the ``last`` one (and at least one pixel)."""
    return abs(pixels - last) <= max(1.0, SAME_PIXELS * last)


def _usable(pixels: int, bbox: tuple[float, float, float, float]) -> bool:
    """Whether the solid model can use a count of ``pixels`` in box ``bbox`` (:func:`_fitted`)."""
    return 0 < pixels <= bbox[2] * bbox[3]


class SensoryMemory:
    """The sensory experiences of anchors frame after frame, each started from its last fit.

    An object keeps its shape: in the solid model an anchor's shape (ball, cylinder, frustum and
    its top ratio) is chosen again only every ``settings.shape_every`` frames and in between just
    fitted again in that shape, which costs a fraction of choosing; every fit starts from the
    anchor's last one. An anchor whose box, camera pose and pixel count are those of its last
    sighting (:func:`_same_sighting`) keeps that sighting's spatial features without a fit (most
    anchors in most frames while the head is still); its colour is read afresh in every frame.
    The experience of an anchor seen whole is kept for when it is out of sight (:meth:`recall`).
    Call :meth:`next_frame` once per frame with the anchors still alive.
    """

    def __init__(self, camera: CameraModel, settings: FeatureSettings = FeatureSettings()) -> None:
        self.camera = camera
        self.settings = settings
        self.frame = 0
        self._fits: dict[str, _Fit] = {}
        self._seen: dict[str, _Sighting] = {}
        self._whole: dict[str, SensoryExperience] = {}
        self.reused = 0
        """How many experiences kept their last spatial features (no fit), for the profile."""

    def of_anchor(self, anchor: Anchor, pose: CameraPose) -> SensoryExperience:
        """``anchor``'s sensory experience in this frame, seen from ``pose``: of its last whole
        sighting when it is remembered out of sight (:meth:`recall`), else :meth:`experience`
        of what it shows now."""
        exp = self.recall(anchor.id) if anchor.remembered else None
        if exp is None:
            exp = self.experience(
                anchor.id,
                anchor.bbox,
                anchor.histograms,
                pose,
                # A count from an earlier frame need not fit a predicted box.
                pixels=anchor.pixels if anchor.visible else None,
                whole=anchor.whole,
            )
        return exp

    def experience(
        self,
        anchor_id: str,
        bbox: tuple[float, float, float, float],
        histograms: np.ndarray,
        pose: CameraPose,
        pixels: int | None = None,
        whole: bool = False,
    ) -> SensoryExperience:
        """:func:`sensory_experience` of anchor ``anchor_id`` in the current frame; ``whole``:
        the anchor is seen whole (its box not cut by the image's border or a nearer object), so
        this is what :meth:`recall` gives from now on."""
        seen = self._seen.get(anchor_id)
        if seen is not None and _same_sighting(
            seen, bbox, pixels, pose, self._reads_count(anchor_id)
        ):
            before = seen.pixels
            if before is not None and pixels is not None and not _same_count(before, pixels):
                # (noted as a fit would note it: the next frames compare with this count)
                seen = self._seen[anchor_id] = seen._replace(pixels=pixels)
            self.reused += 1
            luminance, green_red, yellow_blue = (float(v) for v in histogram_means(histograms))
            experience = replace(
                seen.experience, luminance=luminance, green_red=green_red, yellow_blue=yellow_blue
            )
        else:
            last = self._fits.get(anchor_id)
            experience, fit = _experience(
                bbox, histograms, self.camera, pose, self.settings, pixels, last, self.frame
            )
            if fit.solid is None and last is not None and last.solid is not None:
                fit = fit._replace(solid=last.solid, decided=last.decided)  # no count this frame
            self._fits[anchor_id] = fit
            self._seen[anchor_id] = _Sighting(bbox, pixels, pose, experience)
        if whole:
            self._whole[anchor_id] = experience
        return experience

    def _reads_count(self, anchor_id: str) -> bool:
        """Whether the fit of anchor ``anchor_id`` in this frame would read its pixel count: a
        ball's and the choice of a shape (none made yet, or ``shape_every`` frames after the
        last) do; a cylinder's and a frustum's refit read only the box. (A count that flickers
        by one cell of perception's grid, 4 pixels at 640x480, moves by more than
        :data:`SAME_PIXELS` of a small object's.)"""
        if self.settings.model != "solid":
            return False
        fit = self._fits.get(anchor_id)
        return (
            fit is None
            or fit.solid is None
            or fit.solid.shape == "ball"
            or self.frame - fit.decided >= self.settings.shape_every
        )

    def recall(self, anchor_id: str) -> SensoryExperience | None:
        """The experience of anchor ``anchor_id`` when it was last seen whole (None: never)."""
        return self._whole.get(anchor_id)

    def next_frame(self, alive: Iterable[str]) -> None:
        """Forget the anchors not in ``alive`` and count one frame."""
        keep = set(alive)
        self._fits = {i: f for i, f in self._fits.items() if i in keep}
        self._seen = {i: s for i, s in self._seen.items() if i in keep}
        self._whole = {i: e for i, e in self._whole.items() if i in keep}
        self.frame += 1
