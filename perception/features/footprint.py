"""Upright solids on the ground whose image has a given bounding box (and pixel count).

A bounding box has four numbers (its left, right, top and bottom edge); an upright cylinder
standing on the ground has four unknowns (the centre x, y of its footprint, its diameter and its
height). So, with the camera's pose known, one cylinder fits, and Newton's method finds it from a
nearby start. Unlike the chapter's construction this accounts for the perspective of a camera that
looks down (the top sticks out sideways and its far rim is the bounding box's top edge) and for the
lean of vertical edges away from the image centre.

A cylinder reads objects whose silhouette narrows upwards (cones, balls, toys) too low: their
top edge in the image is an apex or a crown, nearer than a full-width far rim. The silhouette's
pixel count is a fifth measurement that tells them apart; :func:`fit_solid` uses it to choose,
simplest first, among the solids of revolution that explain box and count:

1. a ball (3 unknowns), when the one that best fits the four edges and the count together (least
   squares, each weighed by its noise) is within that noise: chi-square below :data:`BALL_CHI2`;
2. the cylinder, when the count is at least that of the square prism with the cylinder's box seen
   corner-on, less :data:`PRISM_Z` standard deviations of the noise: boxes, whose corners cut their
   silhouette's area below a cylinder's, read right as cylinders (their far top corner is where a
   cylinder's far rim would be), and so do frusta that narrow only a little (top diameter above
   about 0.7 of the bottom's: their heights then come out at most about 5 % low);
3. else a frustum (5 unknowns) whose top diameter is k times its bottom's, k in [0, 1] (0: a cone),
   with exactly the box and the count; k clipped to [0, 1] keeps the box and lets the count go.

The noise is that of a lattice of pixel centres: each edge of a box of whole pixels lies anywhere
within half a pixel of the outline it was rounded from (standard deviation :data:`EDGE_SIGMA`),
and a count scatters by :data:`COUNT_NOISE`. Both tests weigh it, so a small silhouette, whose
box and count say little, is not forced into a ball or a frustum by a fixed relative tolerance:
most balls of 100-300 pixels have a count 5-9 % off the area of the ball that the box alone
fits, because the box's rounding moves that ball's diameter by up to a pixel.

Counts under :data:`MIN_COUNT` pixels are too coarse for this: then the cylinder (with a few
pixels per object the noise admits nearly any solid, and a ball or a frustum read from them is
worse than the cylinder: 28 % against 16 % median height error for the 176x144 camera).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Literal, NamedTuple

import cv2
import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose
from percept.perception.features.images_kernels import outline_images
from percept.perception.features.newton_kernels import BALL, BOX, FRUSTUM, solid_newton
from percept.perception.features.solids_kernels import balls, frusta

_RING = 16  # points per rim of the cylinder fit: the outline is then within 2 % of the circle's
_FINE = 32  # points per rim where the area counts: a 32-gon has 99.4 % of its circle's area
_STEP = 1e-5  # metres, for the numeric Jacobian
_TOLERANCE = 1e-3  # pixels
_SETTLED = 1e-6  # metres: a step this small moves an image by about a thousandth of a pixel
_BALL_SETTLED = 0.05  # noise deviations: a ball's outline polygon turns with it, so its steps
# jitter by some micrometres; a step that moves no measurement by a twentieth of its noise is done
EDGE_SIGMA = 1.0 / np.sqrt(12.0)
"""Pixels: the standard deviation of a box edge, which is uniformly within half a pixel of the
outline it was rounded from."""
COUNT_NOISE = 0.3
"""The standard deviation of a pixel count, in square roots of its outline's length in pixels
(a lattice count's rounding; 0.29-0.38 on the simulated balls of 60-1000 pixels)."""
BALL_CHI2 = -2.0 * np.log(0.01)
"""Chi-square (9.21) under which a ball is taken: its 99 % quantile for the 2 degrees of freedom
left when a ball's 3 unknowns are fitted to 5 measurements (4 edges and the count)."""
MIN_COUNT = (2.0 * np.sqrt(np.pi) * (2.0 * COUNT_NOISE) ** 2 / 0.05**2) ** (2.0 / 3.0)
"""Pixels (64): below this area two standard deviations of the count of a round outline are more
than 5 % of it, more than the area by which a ball, a box and a cylinder with the same box
differ."""
PRISM_Z = 2.33
"""Standard deviations of the noise (one-sided 99 %) by which a count may fall short of the
corner-on prism's area and still be a box's (the cylinder is taken)."""


class Solid(NamedTuple):
    """An upright solid of revolution standing on the ground (metres)."""

    shape: Literal["ball", "cylinder", "frustum"]
    x: float
    """Centre of the footprint (the ball's point of contact)."""
    y: float
    width: float
    """Diameter (of a frustum: at the bottom)."""
    height: float
    k: float = 1.0
    """A frustum's top diameter over its bottom's (1 for a cylinder and a ball)."""


def _circle(points: int) -> np.ndarray:
    """(points, 2) on the circle of unit diameter around the origin."""
    angles = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    return 0.5 * np.column_stack([np.cos(angles), np.sin(angles)])


_COARSE_RIM = _circle(_RING)
_FINE_RIM = _circle(_FINE)
_UNWEIGHTED = (np.ones(4), np.ones(4))  # a box's edges: pixels (sigma), weighed alike (weights)


def _pinhole(camera: CameraModel, pose: CameraPose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pose's ``R``, ``t`` and the intrinsics ``K`` of an undistorted camera as the compiled
    kernels take them (contiguous float64: one compiled signature)."""
    return (
        np.ascontiguousarray(pose.R, float),
        np.ascontiguousarray(pose.t, float),
        np.ascontiguousarray(camera.K, float),
    )


def _compiled_fit(
    kind: int,
    target: np.ndarray,
    start: np.ndarray,
    k: float,
    weights: tuple[np.ndarray, np.ndarray],
    rim: np.ndarray,
    camera: CameraModel,
    pose: CameraPose,
    iterations: int = 15,
) -> np.ndarray | None:
    """:func:`_newton` for a solid of ``kind`` (:func:`solid_newton`) as one compiled loop,
    for an undistorted camera: the parameters found, or None. ``weights``: each measurement's
    sigma and weight. A ball's steps settle on its own size change (:data:`_BALL_SETTLED`)."""
    R, t, K = _pinhole(camera, pose)
    moved = _BALL_SETTLED if kind == BALL else 0.0
    sigma, weight = weights
    found, p = solid_newton(
        kind, target, start, k, sigma, weight, rim, R, t, K,
        iterations, _STEP, _TOLERANCE, _SETTLED, moved,
    )  # fmt: skip
    return p if found else None


def _image(camera: CameraModel, pose: CameraPose, points: np.ndarray, area: bool) -> np.ndarray:
    """(left, right, top, bottom[, area]) in pixels (n, 4 or 5) of the images of point sets
    (n, m, 3); the area is that of their convex hull. NaN where a set is not wholly in front of
    the camera."""
    if not camera.distorted:  # one compiled loop (the same projection)
        images = outline_images(points, *_pinhole(camera, pose), area)
        return images if area else images[:, :4]
    n = len(points)
    uv = camera.project((points.reshape(-1, 3) - pose.t) @ pose.R).reshape(n, -1, 2)
    box = np.empty((n, 2, 2))  # (u, v) x (least, most): left, right, top, bottom
    box[:, :, 0], box[:, :, 1] = uv.min(axis=1), uv.max(axis=1)
    edges = box.reshape(n, 4)
    if not area:
        return edges
    areas = np.full(n, np.nan)
    for i, outline in enumerate(uv):
        if np.isfinite(outline).all():
            areas[i] = cv2.contourArea(cv2.convexHull(outline.astype(np.float32)))
    return np.column_stack([edges, areas])


def _newton(
    measure: Callable[[np.ndarray], np.ndarray],
    target: np.ndarray,
    start: np.ndarray,
    iterations: int,
    scale: np.ndarray | None = None,
    clip: Callable[[np.ndarray], bool] | None = None,
    moved: float | None = None,
) -> np.ndarray | None:
    """Parameters p near ``start`` with ``measure(p) = target``, by Newton's method (Gauss-Newton,
    the least-squares p, when there are more measurements than unknowns).

    ``measure`` maps parameter rows (n, len(p)) to measurement rows (n, len(target)); ``scale``
    turns residuals into pixels (for the convergence test). None when a step leaves the solids of
    positive size (p[2], p[3]) in front of the camera or Newton's method does not settle.
    ``clip(p)`` may clip p in place; when it did (returns True), that p is the answer. ``moved``:
    also settled when a step changes no scaled measurement by as much (for measurements whose
    numeric Jacobian is too rough for a step to fall under :data:`_SETTLED` metres).
    """
    p = np.asarray(start, dtype=float).copy()
    variants = _variants(len(p))
    weights = np.ones(len(target)) if scale is None else scale
    for _ in range(iterations):
        measured = measure(p + variants)
        if not np.isfinite(measured).all():
            return None
        residual = measured[0] - target
        if np.abs(residual * weights).max() < _TOLERANCE:
            return p
        jacobian = (measured[1:] - measured[0]).T / _STEP
        step = _solve(jacobian, residual)
        p -= step
        if (p[2:4] <= 0).any():
            return None
        if clip is not None and clip(p):
            return p
        if np.abs(step).max() < _SETTLED:  # without meeting the target: the least-squares p
            return p
        if moved is not None and np.abs((jacobian @ step) * weights).max() < moved:
            return p
    return None


@functools.cache
def _variants(unknowns: int) -> np.ndarray:
    """The rows added to the parameters for a measurement and its numeric Jacobian: none, then
    each unknown moved by :data:`_STEP` (read only)."""
    rows = np.vstack([np.zeros(unknowns), np.eye(unknowns) * _STEP])
    rows.flags.writeable = False
    return rows


def _solve(jacobian: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """The least-squares step: of a square system by LU decomposition (a fifth of the cost of
    ``lstsq``'s SVD, which a singular one falls back to, for its least-norm step)."""
    if jacobian.shape[0] == jacobian.shape[1]:
        try:
            return np.linalg.solve(jacobian, residual)
        except np.linalg.LinAlgError:
            pass
    return np.linalg.lstsq(jacobian, residual, rcond=None)[0]


def fit_cylinder(
    camera: CameraModel,
    pose: CameraPose,
    edges: tuple[float, float, float, float],
    start: tuple[float, float, float, float],
    iterations: int = 10,
) -> tuple[float, float, float, float] | None:
    """Footprint centre x, y, diameter and height of the upright cylinder whose image spans
    ``edges`` (left, right, top, bottom in pixels), found from the estimate ``start``.

    None when Newton's method does not reach a cylinder of positive size in front of the camera
    (then ``start`` is the better answer).
    """
    return fit_frustum_box(camera, pose, edges, 1.0, start, iterations, _COARSE_RIM)


def fit_frustum(
    camera: CameraModel,
    pose: CameraPose,
    edges: tuple[float, float, float, float],
    area: float,
    start: tuple[float, float, float, float],
    iterations: int = 15,
) -> tuple[float, float, float, float, float] | None:
    """Footprint centre x, y, bottom diameter, height and top-to-bottom ratio k in [0, 1] of the
    upright frustum whose image spans ``edges`` and has ``area`` square pixels, found from the
    footprint and size ``start`` (k starts half-way, a cylinder's k = 1 being a kink of the
    box, or else at a cone).

    Where no k in [0, 1] gives the area, k is clipped and the box alone is fitted. None when
    Newton's method does not reach a frustum of positive size in front of the camera.
    """
    rim = _FINE_RIM
    target = np.array([*edges, area], dtype=float)
    # The area in pixels: residual / sqrt(area) is about the shift of the outline it needs.
    scale = np.array([1.0, 1.0, 1.0, 1.0, 1.0 / np.sqrt(area)])

    def measure(p: np.ndarray) -> np.ndarray:
        return _image(camera, pose, frusta(p, rim), True)

    def clip(p: np.ndarray) -> bool:
        k = min(max(p[4], 0.0), 1.0)
        clipped, p[4] = k != p[4], k
        return bool(clipped)

    def fitted(start: np.ndarray) -> np.ndarray | None:
        if camera.distorted:
            return _newton(measure, target, start, iterations, scale, clip)
        weights = (np.ones(5), scale)
        return _compiled_fit(FRUSTUM, target, start, 1.0, weights, rim, camera, pose, iterations)

    # Half-way first; from there Newton's method can step to a negative size where a cone's
    # box is far from the cylinder's, and a cone is then the better start.
    for k0 in (0.5, 0.0):
        p = fitted(np.array([*start, k0]))
        if p is not None:
            break
    else:
        return None
    k = float(p[4])
    if 0.0 < k < 1.0:
        return (float(p[0]), float(p[1]), float(p[2]), float(p[3]), k)
    q = fit_frustum_box(camera, pose, edges, k, p[:4], iterations)
    return None if q is None else (*q, k)


def fit_frustum_box(
    camera: CameraModel,
    pose: CameraPose,
    edges: tuple[float, float, float, float],
    k: float,
    start: tuple[float, float, float, float] | np.ndarray,
    iterations: int = 15,
    rim: np.ndarray = _FINE_RIM,
) -> tuple[float, float, float, float] | None:
    """Footprint centre x, y, bottom diameter and height of the upright frustum of top-to-bottom
    ratio ``k`` whose image spans ``edges`` (the box alone), found from ``start``, its rims drawn
    with the points of ``rim``. None when Newton's method does not reach one of positive size in
    front of the camera."""
    if not camera.distorted:  # the same steps as one compiled loop
        target, p = np.asarray(edges, float), np.array(start, float)
        q = _compiled_fit(BOX, target, p, float(k), _UNWEIGHTED, rim, camera, pose, iterations)
        return None if q is None else (float(q[0]), float(q[1]), float(q[2]), float(q[3]))

    def box(q: np.ndarray) -> np.ndarray:
        params = np.empty((len(q), 5))
        params[:, :4], params[:, 4] = q, k
        return _image(camera, pose, frusta(params, rim), False)

    q = _newton(box, np.asarray(edges, float), np.asarray(start, float), iterations)
    return None if q is None else (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def count_sigma(pixels: float) -> float:
    """Standard deviation (pixels) of the count of a round silhouette of about ``pixels``
    pixels: :data:`COUNT_NOISE` square roots of its outline's length."""
    return COUNT_NOISE * float(np.sqrt(2.0 * np.sqrt(np.pi * pixels)))


def fit_ball(
    camera: CameraModel,
    pose: CameraPose,
    edges: tuple[float, float, float, float],
    pixels: float,
    start: tuple[float, float, float],
    iterations: int = 15,
) -> tuple[tuple[float, float, float], float] | None:
    """Point of contact x, y and diameter of the ball on the ground whose image best spans
    ``edges`` and covers ``pixels`` pixels (least squares weighed by :data:`EDGE_SIGMA` and
    :func:`count_sigma`: three unknowns, five measurements), found from ``start``; with the
    chi-square of its residuals. None when no ball of positive size in front of the camera is
    reached."""
    sigma = np.array([EDGE_SIGMA] * 4 + [count_sigma(pixels)])
    target = np.array([*edges, pixels], dtype=float) / sigma
    cx, cy, cz = (float(v) for v in pose.t)

    def measure(p: np.ndarray) -> np.ndarray:
        return _image(camera, pose, balls(p, cx, cy, cz, _FINE_RIM), True) / sigma

    if camera.distorted:
        p = _newton(measure, target, np.asarray(start, float), iterations, moved=_BALL_SETTLED)
    else:  # the same steps as one compiled loop
        p0, weights = np.array(start, float), (sigma, np.ones(5))
        p = _compiled_fit(BALL, target, p0, 1.0, weights, _FINE_RIM, camera, pose, iterations)
    if p is None:
        return None
    residual = measure(p[None])[0] - target
    if not np.isfinite(residual).all():
        return None
    return (float(p[0]), float(p[1]), float(p[2])), float(residual @ residual)


def _corner_on_prism_area(
    camera: CameraModel, pose: CameraPose, cylinder: tuple[float, float, float, float]
) -> float:
    """Image area of the square prism inscribed in ``cylinder`` (x, y, diameter, height) with
    its corners along and across the line of sight: the least area of a square prism with
    (nearly) the cylinder's bounding box."""
    x, y, d, h = cylinder
    bearing = np.arctan2(y - pose.t[1], x - pose.t[0])
    angles = bearing + np.arange(4) * np.pi / 2
    square = 0.5 * np.column_stack([np.cos(angles), np.sin(angles)])
    points = frusta(np.array([[x, y, d, h, 1.0]]), square)
    return float(_image(camera, pose, points, True)[0, 4])


def fit_solid(
    camera: CameraModel,
    pose: CameraPose,
    edges: tuple[float, float, float, float],
    pixels: float,
    cylinder: tuple[float, float, float, float],
) -> Solid:
    """The simplest solid of revolution on the ground (ball, cylinder, frustum) whose image
    spans ``edges`` (left, right, top, bottom in pixels) and covers ``pixels`` pixels, given the
    ``cylinder`` (x, y, diameter, height) that :func:`fit_cylinder` found for the same edges; that
    cylinder when neither of the others fits (module docstring)."""
    as_cylinder = Solid("cylinder", *cylinder)
    if pixels < MIN_COUNT:
        return as_cylinder
    ball = fit_ball(camera, pose, edges, pixels, cylinder[:3])
    if ball is not None:
        (x, y, d), chi2 = ball
        if chi2 < BALL_CHI2:
            return Solid("ball", x, y, d, d)
    prism = _corner_on_prism_area(camera, pose, cylinder)
    # The prism's area moves with each edge of the box (relative: edge noise over the box's
    # width or height, two edges each) and the count with its own noise.
    wide, high = edges[1] - edges[0], edges[3] - edges[2]
    spread = prism * EDGE_SIGMA * np.sqrt(2.0 / wide**2 + 2.0 / high**2)
    if pixels >= prism - PRISM_Z * np.hypot(spread, count_sigma(pixels)):
        return as_cylinder
    frustum = fit_frustum(camera, pose, edges, pixels, cylinder)
    if frustum is None:
        return as_cylinder
    return Solid("frustum", *frustum)


def refit_solid(
    camera: CameraModel,
    pose: CameraPose,
    edges: tuple[float, float, float, float],
    pixels: float,
    cylinder: tuple[float, float, float, float],
    known: Solid,
) -> Solid:
    """The solid of ``known``'s shape (a frustum: with its ``k``) whose image spans ``edges``
    (a ball: and covers ``pixels``), started from ``known``: an object keeps its shape from frame
    to frame, and fitting it again costs a fraction of choosing it (:func:`fit_solid`). The
    ``cylinder`` when ``known`` is one or the fit fails."""
    if known.shape == "ball" and pixels >= MIN_COUNT:
        ball = fit_ball(camera, pose, edges, pixels, (known.x, known.y, known.width))
        if ball is not None:
            x, y, d = ball[0]
            return Solid("ball", x, y, d, d)
    elif known.shape == "frustum":
        start = (known.x, known.y, known.width, known.height)
        frustum = fit_frustum_box(camera, pose, edges, known.k, start)
        if frustum is not None:
            return Solid("frustum", *frustum, known.k)
    return Solid("cylinder", *cylinder)
