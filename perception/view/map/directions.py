"""The map over viewing directions that the moving-head background lives on.

A cell of the map is a direction from one fixed centre (the mean camera centre of the
calibration), by azimuth (columns, from a reference heading) and elevation (rows, top = up), at
the angular size of one pixel of the grid the frames are worked on. A pixel whose ray meets the
ground (:func:`percept.kinematics.ground.ground_points`) stands for the direction of its ground
point from that centre, any other pixel for the direction of its own ray: so the floor, which
is most of what a robot looking at a table sees, keeps its place in the map when the camera
centre moves with the head (it sits a few centimetres off the pan and tilt axes), and only what
stands above the floor shows that parallax.

The lookup of every pixel of a frame is exact on a coarse lattice of pixels and linear in
between: the map coordinates change smoothly across the image (also at the horizon, where a
ground point 50 m away and the ray's own direction agree to a thousandth of a degree), and the
trigonometry on every pixel would cost more than the rest of a frame. A frame's view takes the
lattice's coordinates (:meth:`Lookup.coarse`) and interpolates them in its own loop, with the
weights of :class:`Lattice` (those of ``cv2.resize``), never writing every pixel's coordinates
out; :meth:`Lookup.__call__` resizes them for the calibration and the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.ground import MAX_DISTANCE
from percept.kinematics.pose import CameraPose
from percept.perception.view.map.directions_kernels import cells_of, ray_directions

LATTICE = 7
"""Pixels between the exact lookups, linear in between (within 0.05 pixel); odd, see
:class:`Lattice`."""
FAR = 1e6
"""Pixels: where a cell behind the camera is put (far outside any image)."""


@dataclass(frozen=True)
class DirectionMap:
    """Where the cells of the map point: ``rows`` x ``cols`` cells of ``resolution`` radians,
    column 0 at azimuth ``heading + azimuth0``, row 0 at elevation ``elevation0`` (top)."""

    centre: np.ndarray
    """(3,) metres in the ground frame: where the directions start."""
    heading: float
    """Azimuth (radians, ground frame) that the map's azimuths are counted from."""
    resolution: float
    azimuth0: float
    elevation0: float
    rows: int
    cols: int

    @property
    def shape(self) -> tuple[int, int]:
        return self.rows, self.cols

    def coordinates(self, pose: CameraPose, rays: np.ndarray) -> np.ndarray:
        """(N, 2) float32 map coordinates (column, row) of camera-frame rays (N, 3) seen from
        ``pose``."""
        # Contiguous float64 arrays: the kernels' one signature (perception.warm).
        d = ray_directions(
            np.ascontiguousarray(rays, dtype=float),
            np.ascontiguousarray(pose.R, dtype=float),
            np.ascontiguousarray(pose.t, dtype=float),
            self.centre,
            MAX_DISTANCE,
        )
        return cells_of(np.arctan2(d[1], d[0]), np.arctan2(d[2], d[3]), self._geometry)

    @cached_property
    def _geometry(self) -> np.ndarray:
        return np.array([self.heading, self.resolution, self.azimuth0, self.elevation0])

    def cell_pixels(
        self, pose: CameraPose, camera: CameraModel, box: tuple[int, int, int, int]
    ) -> np.ndarray:
        """Pixels (h, w, 2) float32 of camera ``camera`` at ``pose`` where the cells of ``box``
        (left, top, width, height) are seen (exact on a lattice of cells, linear in between;
        far outside the image where a cell is behind the camera)."""
        left, top, width, height = box
        lattice = Lattice(height, width)
        cells = lattice.points + np.array([left, top])
        azimuth = self.heading + self.azimuth0 + cells[:, 0] * self.resolution
        elevation = self.elevation0 - cells[:, 1] * self.resolution
        d = np.column_stack(
            [
                np.cos(elevation) * np.cos(azimuth),
                np.cos(elevation) * np.sin(azimuth),
                np.sin(elevation),
            ]
        )
        # Cells below the centre's horizon stand for a ground point (unless it is too far).
        with np.errstate(divide="ignore"):
            reach = np.where(d[:, 2] < 0, -self.centre[2] / d[:, 2], np.inf)
        ground = reach * np.cos(elevation) <= MAX_DISTANCE
        points = self.centre + np.where(ground, reach, 0.0)[:, None] * d
        # R maps camera -> ground vectors; multiplying from the right maps them back.
        in_camera = np.where(ground[:, None], (points - pose.t) @ pose.R, d @ pose.R)
        uv = np.nan_to_num(camera.project(in_camera), nan=-FAR)
        return lattice.interpolate(uv.reshape(*lattice.shape, 2))

    def footprint(self, pose: CameraPose, camera: CameraModel) -> tuple[int, int, int, int]:
        """The box (left, top, width, height) of the cells that ``camera`` at ``pose`` sees
        (a cell more on every side), within the map."""
        seen = self.coordinates(pose, camera.pixel_rays(_border(camera.width, camera.height)))
        left = max(math.floor(float(seen[:, 0].min())) - 1, 0)
        top = max(math.floor(float(seen[:, 1].min())) - 1, 0)
        right = min(math.ceil(float(seen[:, 0].max())) + 2, self.cols)
        bottom = min(math.ceil(float(seen[:, 1].max())) + 2, self.rows)
        return left, top, max(right - left, 0), max(bottom - top, 0)


def direction_map(
    poses: list[CameraPose], camera: CameraModel, step: int, margin: float
) -> tuple[DirectionMap, tuple[int, int, int, int]]:
    """The map for frames of ``camera`` at ``poses``, on the grid of every ``step``-th pixel,
    and the box (left, top, width, height) of its cells that the frames saw: the map covers
    those and ``margin`` radians more on every side (elevations within +-90 degrees, azimuths
    within one turn)."""
    centre = np.mean([p.t for p in poses], axis=0)
    mean_axis = np.mean([p.R[:, 0] for p in poses], axis=0)  # optical axes in the ground frame
    heading = math.atan2(mean_axis[1], mean_axis[0])
    resolution = step / max(camera.fx, camera.fy)
    # With azimuth0 = elevation0 = 0, coordinates() gives azimuth / resolution and
    # -elevation / resolution.
    probe = DirectionMap(centre, heading, resolution, 0.0, 0.0, 1, 1)
    rays = camera.pixel_rays(_border(camera.width, camera.height))
    seen = np.vstack([probe.coordinates(p, rays) for p in poses]).astype(float) * resolution
    az_lo, az_hi = float(seen[:, 0].min()), float(seen[:, 0].max())
    el_lo, el_hi = -float(seen[:, 1].max()), -float(seen[:, 1].min())
    az0 = max(az_lo - margin, -math.pi)
    el0 = min(el_hi + margin, math.pi / 2)
    cols = math.ceil((min(az_hi + margin, math.pi) - az0) / resolution) + 1
    rows = math.ceil((el0 - max(el_lo - margin, -math.pi / 2)) / resolution) + 1
    left, top = math.floor((az_lo - az0) / resolution), math.floor((el0 - el_hi) / resolution)
    right = min(math.ceil((az_hi - az0) / resolution) + 1, cols)
    bottom = min(math.ceil((el0 - el_lo) / resolution) + 1, rows)
    directions = DirectionMap(centre, heading, resolution, az0, el0, rows, cols)
    return directions, (left, top, right - left, bottom - top)


def _border(width: int, height: int, every: int = 4) -> np.ndarray:
    """Pixels along the image's border (what bounds the directions an image sees)."""
    u = np.arange(0, width, every, dtype=float)
    v = np.arange(0, height, every, dtype=float)
    right, bottom = float(width - 1), float(height - 1)
    return np.vstack(
        [
            np.column_stack([u, np.zeros_like(u)]),
            np.column_stack([u, np.full_like(u, bottom)]),
            np.column_stack([np.zeros_like(v), v]),
            np.column_stack([np.full_like(v, right), v]),
            [[right, bottom]],
        ]
    )


class Lattice:
    """Every :data:`LATTICE`-th point of an ``height`` x ``width`` array, from one step before
    the first to at least the last, and the linear interpolation from there to every point
    (``cv2.resize``, which interpolates float images in float: ``cv2.remap`` would round the
    weights to 1/32)."""

    def __init__(self, height: int, width: int) -> None:
        s = LATTICE
        self.size = (height, width)
        self.shape = (math.ceil((height - 1) / s) + 2, math.ceil((width - 1) / s) + 2)
        gv, gu = np.mgrid[0 : self.shape[0], 0 : self.shape[1]]
        self.points = np.column_stack([gu.ravel(), gv.ravel()]).astype(float) * s - s
        """(N, 2) column, row of the lattice points, row by row."""
        self.rows, self.row_weights = _linear_weights(height, self.shape[0])
        self.columns, self.column_weights = _linear_weights(width, self.shape[1])
        """Per row (column) of the array, the two lattice rows (columns) it lies between and
        their float32 weights, those of :meth:`interpolate`: a compiled loop
        (:func:`~percept.perception.view.bounds_kernels.bounds_in_view`) interpolates as it does,
        to the bit."""

    def interpolate(self, coarse: np.ndarray) -> np.ndarray:
        """(height, width, k) float32 from values (rows, cols, k) at the lattice points (a view
        into a larger array)."""
        s = LATTICE
        # resize puts source point j at (j + 0.5) s - 0.5 of its output, which is lattice
        # point j's place, s (j - 1), plus s + (s - 1) / 2: a whole number for odd s.
        rows, cols = self.shape
        big = cv2.resize(coarse.astype(np.float32), (cols * s, rows * s))
        off = s + (s - 1) // 2
        height, width = self.size
        return big[off : off + height, off : off + width]  # rows contiguous: OpenCV takes it


def _linear_weights(size: int, points: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``size`` places along an axis of :class:`Lattice` with ``points`` lattice
    points: (size, 2) the two points it lies between and (size, 2) float32 their weights, as
    ``cv2.resize`` computes them for the crop that :meth:`Lattice.interpolate` keeps (the
    source place in double, cast to float, its floor, the fraction in float)."""
    s = LATTICE
    place = np.arange(size) + s + (s - 1) // 2
    f = ((place + 0.5) * (1.0 / s) - 0.5).astype(np.float32)
    first = np.floor(f).astype(np.intp)
    fraction = f - first.astype(np.float32)
    # Where the fraction is 0 the second point has no weight (and resize clamps it likewise).
    second = np.minimum(first + 1, points - 1)
    weights = np.column_stack([np.float32(1.0) - fraction, fraction]).astype(np.float32)
    return np.column_stack([first, second]), weights


class Lookup:
    """Map coordinates of every pixel of the frames' grid, for one camera."""

    def __init__(self, camera: CameraModel, step: int, grid: tuple[int, int]) -> None:
        self.grid = grid
        self.lattice = Lattice(*grid)
        self.rays = camera.pixel_rays(self.lattice.points * step)
        """Camera-frame rays of the lattice points (the lens does not change)."""

    def __call__(self, directions: DirectionMap, pose: CameraPose) -> np.ndarray:
        """(H, W, 2) float32 map coordinates of the grid's pixels seen from ``pose``."""
        return self.lattice.interpolate(self.coarse(directions, pose))

    def coarse(self, directions: DirectionMap, pose: CameraPose) -> np.ndarray:
        """(rows, cols, 2) float32 map coordinates of the lattice points seen from ``pose``."""
        return directions.coordinates(pose, self.rays).reshape(*self.lattice.shape, 2)
