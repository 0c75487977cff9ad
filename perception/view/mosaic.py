"""The background over viewing directions: what the still model of §4.1 is per pixel, the mosaic
is per cell of a :class:`~percept.perception.view.map.directions.DirectionMap`, so that it holds for
any head pose.

Calibration resamples every (frame, pose) into the map and takes each cell's statistics over the
frames that saw it, with the same estimators as the still model (the clipped mean ignores what
passed by). A cell no frame saw is *unknown*: its bounds are the whole 0-255 range, so it is
never foreground. It is learned from the frames themselves once it was seen for ``learn_time``
seconds without motion and outside every anchor's box (the running mean and deviation of those
samples become its statistics).

The foreground bounds of each cell take in those of its neighbours (``spread``): the alignment
of a frame with the map is good to a fraction of a cell after the refinement, but on a textured
floor a fraction of a cell is a change of many grey levels.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path

import cv2
import numpy as np

from percept.perception.params import BackgroundParams, ViewParams
from percept.perception.segmentation.background import MAD_TO_SIGMA, CalibrationError
from percept.perception.tracking.motion import Motion
from percept.perception.view.cells_kernels import cell_bounds, tiles
from percept.perception.view.learning_kernels import accumulate, fresh_samples, settle
from percept.perception.view.map.directions import DirectionMap

MIN_VIEWS = 3
"""Calibration frames (at most all of them) that must have seen a cell for it to be known."""

TILE = 64
"""Cells: the bounds of cells learned in one frame are recomputed per tile of this size
(:func:`~percept.perception.view.cells_kernels.tiles`)."""

CHUNK_SAMPLES = 1 << 21
"""Samples per chunk of rows while computing statistics."""

_KEYS = ("mosaic_mean", "mosaic_sigma", "mosaic_known", "mosaic_geometry")


class ViewMosaic:
    """Mean and deviation of Y, Cr, Cb per direction, which directions are known, and the
    bounds of the foreground and motion tests per cell (uint8)."""

    def __init__(
        self,
        directions: DirectionMap,
        mean: np.ndarray,
        sigma: np.ndarray,
        known: np.ndarray,
        background: BackgroundParams,
        view: ViewParams,
        motion_k: float,
    ) -> None:
        if mean.shape != (*directions.shape, 3) or sigma.shape != mean.shape:
            raise ValueError(f"mosaic of {directions.shape} cannot hold {mean.shape}")
        self.directions = directions
        self.mean, self.sigma = mean.astype(np.float32), sigma.astype(np.float32)
        self.known = known.astype(bool)
        self.background, self.view, self.motion_k = background, view, motion_k
        self.version = 0
        """Counts the changes of the bounds (a cell learned), for caches of a view's bounds."""
        self.brightness = np.zeros(directions.shape, np.uint8)
        """Mean Y (at least 1) where known, 0 where not: what frames are aligned with."""
        self.words = np.zeros((directions.rows * directions.cols + 1, 3), np.uint32)
        """Per cell (flat index), as :func:`cell_words` packs them for
        :func:`~percept.perception.view.bounds_kernels.bounds_in_view`: the lower foreground
        bounds and the brightness, the upper ones, and the upper bounds of the frame-to-frame
        difference (the motion test); the last row those of a direction outside the map."""
        out, dark = self.outside, np.zeros((), np.uint8)
        self.words[-1] = cell_words(out[0:3], out[3:6], out[6:9], dark)
        self._learning = _Learning(directions.shape)
        self._bounds(0, directions.rows, 0, directions.cols)

    @property
    def unknown_motion_bound(self) -> int:
        """The motion bound of a direction with no statistics (``sigma_min`` only)."""
        return int(min(255, math.floor(self.motion_k * self.background.sigma_min)))

    def _bounds(self, top: int, bottom: int, left: int, right: int) -> None:
        """Recompute the bounds of rows top:bottom, columns left:right (and of the cells whose
        spread reaches into them): :func:`~percept.perception.view.cells_kernels.cell_bounds`."""
        words = self.words[:-1].reshape(*self.directions.shape, 3)
        cell_bounds(
            self.mean,
            self.sigma,
            self.known,
            self.background.k,
            self.motion_k,
            self.background.sigma_min,
            self.unknown_motion_bound,
            self.view.spread,
            (top, bottom, left, right),
            self.brightness,
            words,
        )
        self.version += 1

    @property
    def outside(self) -> np.ndarray:
        """The bounds of a direction outside the map (as of an unknown cell: never foreground,
        the motion bound of ``sigma_min``)."""
        return np.array([0] * 3 + [255] * 3 + [self.unknown_motion_bound] * 3, np.uint8)

    def brightness_at(self, cells: np.ndarray) -> np.ndarray:
        """The mean Y (0 where unknown or outside the map) of the cells nearest to map
        coordinates ``cells`` (H, W, 2) float32, what frames are aligned with."""
        return cv2.remap(  # type: ignore[call-overload]
            self.brightness, cells, None, cv2.INTER_NEAREST, borderValue=0
        )

    # -- calibration ----------------------------------------------------------------------------

    @classmethod
    def calibrate(
        cls,
        directions: DirectionMap,
        samples: np.ndarray,
        seen: np.ndarray,
        box: tuple[int, int, int, int],
        background: BackgroundParams,
        view: ViewParams,
        motion_k: float,
    ) -> ViewMosaic:
        """The mosaic from ``samples`` (frames, h, w, 3) uint8 of the cells of ``box`` (left,
        top, w, h) and which of them each frame ``seen`` (frames, h, w) bool."""
        left, top, width, height = box
        mean = np.zeros((*directions.shape, 3), np.float32)
        sigma = np.zeros_like(mean)
        known = np.zeros(directions.shape, bool)
        m, s, count = masked_statistics(samples, seen, background)
        inside = (slice(top, top + height), slice(left, left + width))
        mean[inside], sigma[inside] = m, s
        known[inside] = count >= min(MIN_VIEWS, len(samples))
        return cls(directions, mean, sigma, known, background, view, motion_k)

    # -- learning -------------------------------------------------------------------------------

    def learn(
        self,
        nearest: np.ndarray,
        ycc: np.ndarray,
        moved: Motion,
        boxes: np.ndarray,
        seen: np.ndarray,
        t: float,
    ) -> int:
        """Learn unknown cells from the grid pixels of one frame that look at them: ``nearest``
        (H, W) int32 the flat index of each pixel's nearest cell (-1: outside the map), ``ycc``
        (H, W, 3) their values, quiet where nothing ``moved`` (asked of those pixels only) outside
        the ``boxes`` (n, 4, grid pixels) of the anchors (which may hide an object that is not
        background); pixels ``seen`` (H, W) bool against a known cell are skipped. Returns how
        many cells became known."""
        known = self.known.ravel()
        previous, upper, size = moved.per_pixel(seen)
        flat, values, calm = fresh_samples(nearest, ycc, previous, upper, size, boxes, seen, known)
        if len(flat) == 0:
            return 0
        learned = self._learning.add(flat, values, calm, t, self.view.learn_time)
        if len(learned) == 0:
            return 0
        self._learning.settle(learned, self.mean, self.sigma, self.known)
        # Cells learned in one frame lie at both edges of a turning view, often a whole view
        # apart: the box of all of them would recompute a hundred times as many bounds.
        for top, bottom, left, right in tiles(learned, self.directions.cols, TILE).tolist():
            self._bounds(top, bottom, left, right)
        return len(learned)

    def forget(self, cells: np.ndarray) -> None:
        """Make the flat ``cells`` unknown again: their statistics hold something that is no
        longer there (a ghost of someone who stood there during calibration). Unknown, they
        are never foreground, and :meth:`learn` learns them anew from the frames."""
        if len(cells) == 0:
            return
        self.known.reshape(-1)[cells] = False
        self._learning.restart(cells)
        for top, bottom, left, right in tiles(cells, self.directions.cols, TILE).tolist():
            self._bounds(top, bottom, left, right)

    # -- files ----------------------------------------------------------------------------------

    def arrays(self) -> dict[str, np.ndarray]:
        """What :meth:`load` reads back (saved beside the still model's ``mean`` and ``sigma``)."""
        d = self.directions
        geometry = np.array(
            [*d.centre, d.heading, d.resolution, d.azimuth0, d.elevation0, d.rows, d.cols]
        )
        return {
            "mosaic_mean": self.mean,
            "mosaic_sigma": self.sigma,
            "mosaic_known": self.known,
            "mosaic_geometry": geometry,
        }

    @classmethod
    def load(
        cls, path: str | Path, background: BackgroundParams, view: ViewParams, motion_k: float
    ) -> ViewMosaic | None:
        """The mosaic saved in ``path`` by :meth:`arrays`, or None when it holds none (a still
        calibration)."""
        try:
            with np.load(path) as data:
                if not all(k in data for k in _KEYS):
                    return None
                g = data["mosaic_geometry"]
                directions = DirectionMap(
                    centre=g[:3].copy(),
                    heading=float(g[3]),
                    resolution=float(g[4]),
                    azimuth0=float(g[5]),
                    elevation0=float(g[6]),
                    rows=int(g[7]),
                    cols=int(g[8]),
                )
                return cls(
                    directions,
                    data["mosaic_mean"],
                    data["mosaic_sigma"],
                    data["mosaic_known"],
                    background,
                    view,
                    motion_k,
                )
        except (OSError, EOFError, KeyError, ValueError, IndexError, zipfile.BadZipFile) as err:
            raise CalibrationError(f"{path}: not a moving-head background ({err})") from None


def cell_words(
    lower: np.ndarray, upper: np.ndarray, moved: np.ndarray, brightness: np.ndarray
) -> np.ndarray:
    """(..., 3) uint32: the bounds of cells (``lower``, ``upper``, ``moved`` (..., 3) uint8)
    as three words each, a byte per channel from the lowest (little-endian, as the kernel writes
    them out), and ``brightness`` (...) uint8 in the lower bounds' fourth byte."""
    out = np.zeros((*brightness.shape, 12), np.uint8)
    out[..., 0:3], out[..., 3] = lower, brightness
    out[..., 4:7], out[..., 8:11] = upper, moved
    return out.view(np.uint32)


class _Learning:
    """Running sums of the samples of unknown cells seen quietly, and since when."""

    def __init__(self, shape: tuple[int, int]) -> None:
        cells = shape[0] * shape[1]
        self.sum = np.zeros((cells, 3), np.float64)
        self.squares = np.zeros((cells, 3), np.float64)
        self.n = np.zeros(cells, np.int64)
        self.since = np.full(cells, np.nan)

    def add(
        self, cells: np.ndarray, values: np.ndarray, quiet: np.ndarray, t: float, learn_time: float
    ) -> np.ndarray:
        """Add the quiet samples, restart the cells with a restless one; the cells learned."""
        return accumulate(
            cells, values, quiet, t, learn_time, self.sum, self.squares, self.n, self.since
        )

    def restart(self, cells: np.ndarray) -> None:
        """Drop what was summed of the ``cells``: they are learned from the next quiet sample."""
        self.sum[cells], self.squares[cells], self.n[cells] = 0.0, 0.0, 0
        self.since[cells] = np.nan

    def settle(
        self, cells: np.ndarray, mean: np.ndarray, sigma: np.ndarray, known: np.ndarray
    ) -> None:
        """Give the ``cells`` learned their statistics in ``mean``, ``sigma`` (H, W, 3) and
        ``known`` (H, W), and restart their sums."""
        settle(
            cells, self.sum, self.squares, self.n, self.since,
            mean.reshape(-1, 3), sigma.reshape(-1, 3), known.ravel(),
        )  # fmt: skip


def masked_statistics(
    samples: np.ndarray, seen: np.ndarray, params: BackgroundParams
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-cell ``(mu, sigma, count)`` of (frames, h, w, 3) uint8 ``samples`` over the frames
    that ``seen`` each cell, by ``params.estimator`` (the still model's estimators, for cells
    that not every frame saw). Cells no frame saw get 0, 0, 0."""
    frames, height, width, _ = samples.shape
    mean = np.empty((height, width, 3), np.float32)
    sigma = np.empty_like(mean)
    rows = max(1, CHUNK_SAMPLES // max(1, frames * width * 3))  # bounds the float copies
    for top in range(0, height, rows):
        inside = slice(top, top + rows)
        mean[inside], sigma[inside] = _cell_statistics(samples[:, inside], seen[:, inside], params)
    return mean, sigma, seen.sum(axis=0)


def _cell_statistics(
    samples: np.ndarray, seen: np.ndarray, params: BackgroundParams
) -> tuple[np.ndarray, np.ndarray]:
    x = samples.astype(np.float32)
    x[~seen] = np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        if params.estimator == "mean":
            mean = _nanmean(x)
        else:
            median = _nanmedian(x)
            spread = np.abs(x - median)
            robust = np.maximum(MAD_TO_SIGMA * _nanmedian(spread), 1.0)
            x[~(spread <= params.clip * robust)] = np.nan  # NaN compares False: dropped
            mean = _nanmean(x)
        var = _nanmean((x - mean) ** 2)
    return np.nan_to_num(mean), np.sqrt(np.nan_to_num(var))


def _nanmean(x: np.ndarray) -> np.ndarray:
    n = np.sum(~np.isnan(x), axis=0)
    return np.nansum(x, axis=0) / n


def _nanmedian(x: np.ndarray) -> np.ndarray:
    """Median over axis 0 ignoring NaN: sorted, NaN go last; the middle of the valid ones."""
    ordered = np.sort(x, axis=0)
    n = np.sum(~np.isnan(x), axis=0)
    lo = np.clip((n - 1) // 2, 0, None)[None]
    hi = np.clip(n // 2, 0, None)[None]
    return (np.take_along_axis(ordered, lo, 0)[0] + np.take_along_axis(ordered, hi, 0)[0]) / 2
