"""The compiled kernels: the colour split's pieces against OpenCV's connected components, the
association against the score written out in numpy, the motion in boxes against OpenCV's whole
mask, the marker quads' grey levels against cv2.remap's, the footprint fits against their numpy
steps and their least squares against numpy's lstsq, that no kernel needs scipy, and the cache
folder numba is given."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, rpy_matrix
from percept.perception.colour import Coding, bin_shift, to_ycrcb
from percept.perception.evaluation.synthetic import busy_scene
from percept.perception.features import footprint
from percept.perception.features.images_kernels import hull_area, outline_images
from percept.perception.features.least_squares_kernels import least_squares
from percept.perception.features.newton_kernels import BALL, BOX, FRUSTUM, solid_newton, solve4
from percept.perception.features.solids_kernels import balls, frusta
from percept.perception.light.masks_kernels import share_outside
from percept.perception.light.photometry.order_kernels import median
from percept.perception.params import SplitParams
from percept.perception.segmentation.labelling.regions import find_regions
from percept.perception.segmentation.percepts import PerceptSet, combine
from percept.perception.segmentation.segment import Segmenter
from percept.perception.segmentation.split import split_regions
from percept.perception.segmentation.split_kernels import classify
from percept.perception.tracking.kalman import BoxFilters
from percept.perception.view.learning_kernels import unseen

pytestmark = pytest.mark.timeout(120)

MARGINALS = Coding(16, joint=False)


def blobs(seed: int, width: int = 120, height: int = 90) -> np.ndarray:
    """A 0/1 mask of random ellipses, some of them overlapping."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((height, width), np.uint8)
    for _ in range(6):
        centre = (int(rng.integers(0, width)), int(rng.integers(0, height)))
        axes = (int(rng.integers(3, 25)), int(rng.integers(3, 20)))
        cv2.ellipse(mask, centre, axes, float(rng.uniform(0, 180)), 0, 360, 1, -1)
    return mask


@pytest.mark.parametrize("seed", range(4))
def test_split_pieces_are_opencvs_connected_components(seed: int) -> None:
    mask = blobs(seed)
    rng = np.random.default_rng(seed)
    ycc = rng.integers(0, 256, (*mask.shape, 3), dtype=np.uint8)
    regions = find_regions(mask, ycc, MARGINALS, 5)
    # Three classes in stripes and blocks: regions of several classes, pieces of all sizes.
    ys, xs = np.divmod(regions.pixels, mask.shape[1])
    classes = ((xs // 7) + (ys // 11) * (seed + 1)) % 3
    min_pixels = 4
    percepts = split_regions(regions, classes, 2, min_pixels)

    _, labels = cv2.connectedComponents(mask, connectivity=8)
    image = np.full(mask.shape, -1)
    image.flat[regions.pixels] = classes
    expected = []
    for r in range(len(regions)):
        inside = labels == regions.label_ids[r]
        per_class = [(image[inside] == c).sum() for c in range(3)]
        kept = [c for c in range(3) if per_class[c] >= min_pixels]
        pieces = []
        if len(kept) >= 2:
            for c in kept:
                n, piece, stats, _ = cv2.connectedComponentsWithStats(
                    (inside & (image == c)).astype(np.uint8), connectivity=8
                )
                for k in range(1, n):
                    if stats[k, 4] >= min_pixels:
                        where = piece == k
                        hist = np.stack(
                            [np.bincount(ycc[..., ch][where] >> 4, minlength=16) for ch in range(3)]
                        )
                        pieces.append((r, *stats[k, :5].tolist(), hist / stats[k, 4]))
        if not pieces:  # one class, or no piece large enough: the region whole
            box = regions.boxes[r].tolist()
            pieces = [(r, *box, int(regions.counts[r]), regions.histograms[r])]
        expected += pieces
    got = [
        (int(r), *b.astype(int).tolist(), int(n), h)
        for r, b, n, h in zip(
            percepts.regions, percepts.boxes, percepts.counts, percepts.histograms, strict=True
        )
    ]
    assert sorted(g[:6] for g in got) == sorted(e[:6] for e in expected)
    assert len(got) > len(regions)  # something was cut
    by_key = {e[:6]: e[6] for e in expected}
    for g in got:
        np.testing.assert_array_equal(g[6], by_key[g[:6]])


def test_association_is_the_highest_score_above_the_thresholds() -> None:
    from percept.perception.tracking.association_kernels import best_models

    rng = np.random.default_rng(7)
    k, n, m = 30, 9, 16
    boxes = np.concatenate([rng.uniform(0, 150, (k, 2)), rng.uniform(5, 40, (k, 2))], axis=1)
    hist = rng.random((k + n, 3, m)) ** 4
    hist /= hist.sum(axis=2, keepdims=True)
    hist, models = hist[:k], hist[k:]
    hist[::2] = models[rng.integers(0, n, k)][::2]  # half of the percepts look like a model
    centres = rng.uniform(0, 170, (n, 2))
    moving = rng.random(n) < 0.5
    t_space, t_color = np.array([0.7, 0.5]), np.array([0.6, 0.4])
    diagonal = float(np.hypot(176, 144))
    best = best_models(boxes, hist, centres, models, moving, t_space, t_color, diagonal)

    d = boxes[:, None, :2] + boxes[:, None, 2:] / 2 - centres[None]
    s_space = 1 - np.hypot(d[..., 0], d[..., 1]) / diagonal
    s_color = np.prod(np.einsum("kcb,ncb->knc", np.sqrt(hist), np.sqrt(models)), axis=2)
    score = np.where(s_space > t_space[moving.astype(int)], s_space, 0) * np.where(
        s_color > t_color[moving.astype(int)], s_color, 0
    )
    expected = np.where(score.max(axis=1) > 0, score.argmax(axis=1), -1)
    np.testing.assert_array_equal(best, expected)
    assert (best >= 0).any() and (best < 0).any()


def reference_correction(
    best: np.ndarray,
    percepts: PerceptSet,
    filters: BoxFilters,
    models: np.ndarray,
    alpha: float,
    last_seen: np.ndarray,
    pixels: np.ndarray,
    t: float,
    size: tuple[int, int],
    turning: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """The tracker's correction as numpy expressions (what :func:`correct` replaced)."""
    hit = best >= 0
    cut = np.zeros(len(filters), bool)
    models = models.copy()
    if not hit.any():
        return models, cut
    taken = PerceptSet(
        percepts.boxes[hit], percepts.histograms[hit], percepts.counts[hit], percepts.regions[hit]
    )
    rows = best[hit]
    if len(rows) > 1 and np.bincount(rows, minlength=len(filters)).max() > 1:
        rows, groups = np.unique(rows, return_inverse=True)
        taken = combine(groups, len(rows), taken)
    left, top, w, h = taken.boxes.T
    cut[rows] = (left < 1) | (top < 1) | (left + w > size[0] - 1) | (top + h > size[1] - 1)
    z = np.concatenate([taken.boxes[:, :2] + taken.boxes[:, 2:] / 2, taken.boxes[:, 2:]], axis=1)
    filters.update(rows, z)
    if turning:
        filters.x[rows[cut[rows]], 4:] = 0.0
    h = (1 - alpha) * models[rows] + alpha * taken.histograms
    models[rows] = h / h.sum(axis=-1, keepdims=True)
    last_seen[rows] = t
    pixels[rows] = taken.counts
    return models, cut


@pytest.mark.parametrize("seed", range(6))
def test_anchor_correction_is_the_numpy_expressions(seed: int) -> None:
    from percept.perception.tracking.anchors_kernels import correct

    rng = np.random.default_rng(seed)
    n, k, m, size = 7, 9, 16 if seed % 2 else 8, (176, 144)
    filters = BoxFilters(0.01, 1.0, 1.0, 1.0)
    filters.add(np.concatenate([rng.uniform(0, 170, (n, 2)), rng.uniform(2, 40, (n, 2))], 1))
    filters.x[:, 4:] = rng.normal(0, 2, (n, 4))
    models = rng.random((n, 3, m)) ** 3
    models /= models.sum(axis=-1, keepdims=True)
    histograms = rng.random((k, 3, m)) ** 3
    histograms /= histograms.sum(axis=-1, keepdims=True)
    boxes = np.concatenate([rng.uniform(-5, 170, (k, 2)), rng.uniform(1, 40, (k, 2))], axis=1)
    # Edges half a pixel inside and outside the image's outermost pixels (the border rule).
    boxes[0:2, 0], boxes[2:4, 1] = 0.5, (1.5, 0.5)
    boxes[4:6, 0] = np.array([size[0] - 0.5, size[0] - 1.5]) - boxes[4:6, 2]
    boxes[6:8, 1] = np.array([size[1] - 0.5, size[1] - 1.5]) - boxes[6:8, 3]
    percepts = PerceptSet(boxes, histograms, rng.integers(5, 900, k), rng.integers(0, 4, k))
    # Seeds 0-1: one percept per model at most; 2-3: some models get several; 4-5: none.
    best = np.full(k, -1, np.intp)
    if seed < 2:
        best[rng.permutation(k)[: n - 1]] = rng.permutation(n)[: n - 1]
    elif seed < 4:
        best[:] = rng.permutation(k) % n
        best[rng.integers(0, k)] = -1
    turning = seed % 2 == 1
    last_seen, pixels = rng.uniform(0, 1, n), rng.integers(0, 500, n)
    mine = BoxFilters(0.01, 1.0, 1.0, 1.0)
    mine.x, mine.cov = filters.x.copy(), filters.cov.copy()
    my_seen, my_pixels = last_seen.copy(), pixels.copy()
    expected = reference_correction(
        best, percepts, filters, models, 0.1, last_seen, pixels, 2.0, size, turning
    )
    got = correct(
        best,
        *(boxes, histograms, percepts.counts, percepts.regions),
        mine.x,
        mine.cov,
        mine.r,
        models,
        0.1,
        my_seen,
        my_pixels,
        2.0,
        *size,
        turning,
    )
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_array_equal(a, b)
    for a, b in ((mine.x, filters.x), (mine.cov, filters.cov), (my_seen, last_seen)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(my_pixels, pixels)
    assert got[0] is not models and (seed >= 4) == np.array_equal(got[0], models)
    assert seed >= 4 or (expected[1].any() and not expected[1].all())


def test_kalman_boxes_and_size_floor_are_numpys() -> None:
    rng = np.random.default_rng(5)
    filters = BoxFilters(0.01, 1.0, 1.0, 1.0)
    filters.add(np.concatenate([rng.uniform(0, 170, (20, 2)), rng.uniform(-1, 3, (20, 2))], 1))
    filters.x[:, 4:] = rng.normal(0, 1, (20, 4))
    filters.x[0, 2] = np.nan
    x = filters.x.copy()
    x[:, :4] += x[:, 4:]
    np.maximum(x[:, 2:4], 1.0, out=x[:, 2:4])
    filters.predict(min_size=1.0)
    np.testing.assert_array_equal(filters.x, x)
    assert np.isnan(filters.x[0, 2]) and (filters.x[1:, 2:4] >= 1).all()
    expected = np.concatenate([x[:, :2] - x[:, 2:4] / 2, x[:, 2:4]], axis=1)
    np.testing.assert_array_equal(filters.boxes, expected)


def test_bounds_in_view_are_cv2_nearest_remaps_of_the_resized_lattice() -> None:
    # The view's bounds are each table's nearest remap at the lattice's map coordinates resized
    # to every pixel (Lattice.interpolate, cv2.resize), outside the map (and behind the camera:
    # NaN) the values of no cell; the brightness is the nearest remap of the map's, the nearest
    # index that of the coordinates rounded half to even.
    from percept.perception.view.bounds_kernels import bounds_in_view
    from percept.perception.view.map.directions import Lattice
    from percept.perception.view.mosaic import cell_words

    rng = np.random.default_rng(5)
    rows, cols = 40, 60
    bounds = rng.integers(0, 256, (rows, cols, 9), dtype=np.uint8)
    brightness = rng.integers(0, 3, (rows, cols), dtype=np.uint8)
    outside = np.array([0, 0, 0, 255, 255, 255, 7, 7, 7], np.uint8)
    lattice = Lattice(45, 62)  # neither side a whole number of lattice steps
    coarse = rng.uniform(-3.0, 64.0, (*lattice.shape, 2)).astype(np.float32)
    coarse[1:3] = np.round(coarse[1:3]) + 0.5  # rows of halves: rounded to even
    coarse[5, 7] = np.nan
    cells = lattice.interpolate(coarse)
    shape = cells.shape[:2]
    lower, upper, moved = (np.empty((*shape, 3), np.uint8) for _ in range(3))
    model = np.empty(shape, np.uint8)
    nearest = np.empty(shape, np.int32)
    words = cell_words(
        np.concatenate([bounds[..., 0:3].reshape(-1, 3), outside[None, 0:3]]),
        np.concatenate([bounds[..., 3:6].reshape(-1, 3), outside[None, 3:6]]),
        np.concatenate([bounds[..., 6:9].reshape(-1, 3), outside[None, 6:9]]),
        np.append(brightness.ravel(), np.uint8(0)),
    )
    bounds_in_view(
        coarse, lattice.columns, lattice.column_weights, lattice.rows, lattice.row_weights,
        words, rows, cols, lower, upper, moved, model, nearest,
    )  # fmt: skip

    def remap(table: np.ndarray, value: tuple[int, ...]) -> np.ndarray:
        return cv2.remap(  # type: ignore[call-overload]
            np.ascontiguousarray(table), np.ascontiguousarray(cells), None, cv2.INTER_NEAREST,
            borderMode=cv2.BORDER_CONSTANT, borderValue=value,
        )  # fmt: skip

    nan = np.isnan(cells).any(axis=2)
    assert nan.any() and not nan.all()
    for got, channels, value in ((lower, slice(0, 3), 0), (upper, slice(3, 6), 255)):
        assert np.array_equal(got[~nan], remap(bounds[..., channels], (value,) * 4)[~nan])
    assert np.array_equal(moved[~nan], remap(bounds[..., 6:9], (7,) * 4)[~nan])
    assert np.array_equal(model[~nan], remap(brightness, (0,) * 4)[~nan])
    x, y = np.rint(cells[..., 0]), np.rint(cells[..., 1])
    inside = (x >= 0) & (x < cols) & (y >= 0) & (y < rows)  # False where NaN
    expected = np.where(inside, np.nan_to_num(y) * cols + np.nan_to_num(x), -1)
    assert np.array_equal(nearest, expected) and (nearest < 0).any() and (nearest >= 0).any()
    assert (np.abs(cells - np.trunc(cells)) == 0.5).any()  # ties were met
    assert list(lower[nan].ravel()) == [0, 0, 0] * nan.sum()
    assert list(moved[nan].ravel()) == [7, 7, 7] * nan.sum()
    assert not model[nan].any() and model.any() and not model.all()


@pytest.mark.parametrize("spread", [0, 1, 2])
def test_cell_bounds_are_the_still_models_eroded_and_dilated(spread: int) -> None:
    # The mosaic's bounds of a tile (and of the cells whose spread reaches into it), to the bit,
    # against the numpy and OpenCV arithmetic they replace: the still model's bounds of the
    # cells, those of unknown cells 0, 255 and the motion bound of sigma_min, eroded (lower)
    # and dilated (upper, motion) with a square of the spread and a replicated border, the
    # brightness the rounded mean Y (at least 1, 0 where unknown); tiles inside the map and at
    # each of its edges, means of halves (rounded to even) and deviations below sigma_min.
    from percept.perception.params import BackgroundParams
    from percept.perception.segmentation.background import BackgroundModel
    from percept.perception.view.cells_kernels import cell_bounds
    from percept.perception.view.mosaic import cell_words

    params, motion_k, unknown_motion = BackgroundParams(), 4.5, 9
    rng = np.random.default_rng(spread)
    rows, cols = 30, 41
    mean = rng.uniform(-5.0, 260.0, (rows, cols, 3)).astype(np.float32)
    mean[::4] = np.round(mean[::4]) + 0.5
    sigma = rng.uniform(0.0, 3.0 * params.sigma_min, (rows, cols, 3)).astype(np.float32)
    # Every other row: a bound that falls on a whole number in float64 arithmetic, give or
    # take a unit of the last place, where float32 arithmetic rounds otherwise.
    scale = params.k * np.maximum(sigma[1::2], params.sigma_min).astype(float)
    whole = np.round(mean[1::2]) + scale
    mean[1::2] = np.nextafter(whole.astype(np.float32), rng.choice([-1e3, 1e3], whole.shape))
    known = rng.random((rows, cols)) < 0.97
    known[5:8, 30:35] = False

    def by_numpy(y0: int, y1: int, x0: int, x1: int) -> tuple[np.ndarray, np.ndarray]:
        still = BackgroundModel(mean, sigma, params)
        lower, upper = still.lower, still.upper
        lower[~known], upper[~known] = 0, 255
        moved = np.clip(np.floor(still.scale(motion_k)), 0, 255).astype(np.uint8)
        moved[~known] = unknown_motion
        square = np.ones((2 * spread + 1, 2 * spread + 1), np.uint8)
        lower = cv2.erode(lower, square, borderType=cv2.BORDER_REPLICATE)
        upper = cv2.dilate(upper, square, borderType=cv2.BORDER_REPLICATE)
        moved = cv2.dilate(moved, square, borderType=cv2.BORDER_REPLICATE)
        mean_y = np.clip(np.rint(mean[..., 0]), 1, 255).astype(np.uint8)
        brightness = np.where(known, mean_y, 0).astype(np.uint8)
        words = cell_words(lower, upper, moved, brightness)
        inner = (slice(y0, y1), slice(x0, x1))
        return words[inner], brightness[inner]

    tiles = [(0, rows, 0, cols), (0, 3, 0, 5), (rows - 2, rows, cols - 7, cols), (10, 11, 20, 21)]
    tiles += [(3, 9, cols - 1, cols), (rows - 1, rows, 0, 1)]
    for top, bottom, left, right in tiles:
        brightness = np.full((rows, cols), 77, np.uint8)
        words = np.full((rows, cols, 3), 0xDEADBEEF, np.uint32)
        cell_bounds(
            mean, sigma, known, params.k, motion_k, params.sigma_min, unknown_motion, spread,
            (top, bottom, left, right), brightness, words,
        )  # fmt: skip
        y0, y1 = max(top - spread, 0), min(bottom + spread, rows)
        x0, x1 = max(left - spread, 0), min(right + spread, cols)
        expected_words, expected_brightness = by_numpy(y0, y1, x0, x1)
        assert np.array_equal(words[y0:y1, x0:x1], expected_words)
        assert np.array_equal(brightness[y0:y1, x0:x1], expected_brightness)
        untouched = np.ones((rows, cols), bool)
        untouched[y0:y1, x0:x1] = False
        assert (words[untouched] == 0xDEADBEEF).all() and (brightness[untouched] == 77).all()
    whole = by_numpy(0, rows, 0, cols)[0].view(np.uint8)  # bounds clipped at both ends met
    lower, upper = whole[..., 0:3], whole[..., 4:7]
    assert (lower[known] == 0).any() and (upper[known] == 255).any()
    assert ((lower > 0) & (upper < 255)).any()


def test_tiles_and_learned_statistics_are_numpys() -> None:
    # The tiles of the cells learned are the boxes of the cells per tile, in the order of the
    # tiles (numpy's stable sort by tile and reduceat), also on a map a whole number of tiles
    # wide; the statistics of a cell learned are numpy's of its sums, in float64 stored as
    # float32, and its sums restart.
    from percept.perception.view.cells_kernels import tiles
    from percept.perception.view.learning_kernels import settle

    def by_numpy(cells: np.ndarray, cols: int, tile: int) -> list[list[int]]:
        y, x = np.divmod(cells, cols)
        key = (y // tile) * (cols // tile + 1) + x // tile
        order = np.argsort(key, kind="stable")
        key, y, x = key[order], y[order], x[order]
        starts = np.flatnonzero(np.diff(key, prepend=-1))
        ends = [np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts) + 1]
        ends += [np.minimum.reduceat(x, starts), np.maximum.reduceat(x, starts) + 1]
        return np.column_stack(ends).tolist()

    rng = np.random.default_rng(11)
    for rows, cols in ((587, 1129), (256, 192)):
        for n in (1, 2, 30, 400):
            cells = np.sort(rng.choice(rows * cols, n, replace=False)).astype(np.intp)
            got = tiles(cells, cols, 64)
            assert got.tolist() == by_numpy(cells, cols, 64)
            assert n < 30 or len(got) > 1
    assert tiles(np.zeros(0, np.intp), 100, 64).shape == (0, 4)

    cells, n = np.array([3, 7, 8], np.intp), np.array([0, 0, 0, 2, 0, 0, 0, 5, 300, 0])
    taken = np.arange(300)[None, None, :] < n[:, None, None]  # each cell's n samples
    values = rng.integers(0, 256, (10, 3, 300)).astype(float) * taken
    sums, squares = values.sum(axis=2), (values**2).sum(axis=2)
    sums[8, 0], squares[8, 0] = 600.0, 1199.0  # a variance below 0 (as by rounding): none
    mean, sigma = np.full((10, 3), 7, np.float32), np.full((10, 3), 7, np.float32)
    expected_mean, expected_sigma = mean.copy(), sigma.copy()
    m = sums[cells] / n[cells][:, None]
    expected_mean[cells] = m
    expected_sigma[cells] = np.sqrt(np.maximum(squares[cells] / n[cells][:, None] - m**2, 0.0))
    known, since = np.zeros(10, bool), np.arange(10.0)
    settle(cells, sums, squares, n, since, mean, sigma, known)
    assert np.array_equal(mean, expected_mean) and np.array_equal(sigma, expected_sigma)
    assert sigma[8, 0] == 0 and (sigma[cells] > 0).sum() == 8
    assert known.tolist() == [i in (3, 7, 8) for i in range(10)]
    assert not sums[cells].any() and not squares[cells].any() and not n[cells].any()
    assert np.isnan(since[cells]).all() and since[0] == 0.0 and sums[9].sum() == 0


def test_the_map_in_view_for_the_ghost_test_is_numpys_gathers() -> None:
    # The map's mean at each pixel's nearest known cell (the frame where the map knows nothing
    # or the pixel lies outside it), and whether its cell was last background at the hold's
    # start or before (outside the map: settled), as numpy's masks and fancy indexing.
    from percept.perception.view.ghosts_kernels import map_in_view

    rng = np.random.default_rng(5)
    height, width, cells = 37, 53, 400
    ycc = rng.integers(0, 256, (height, width, 3), dtype=np.uint8)
    nearest = rng.integers(-1, cells, (height, width)).astype(np.int32)
    known = (nearest >= 0) & (rng.random((height, width)) < 0.8)
    learned = rng.uniform(0, 255, (cells, 3)).astype(np.float32)
    background_at = rng.choice([0.0, 1.5, 2.0, 2.5], cells)
    mean, settled = map_in_view(ycc, nearest, known, learned, background_at, 2.0)
    expected = ycc.astype(np.float32)
    expected[known] = learned[nearest[known]]
    inside = nearest >= 0
    expected_settled = np.ones((height, width), bool)
    expected_settled[inside] = background_at[nearest[inside]] <= 2.0
    assert mean.dtype == np.float32 and np.array_equal(mean, expected)
    assert np.array_equal(settled, expected_settled)
    assert 0 < settled[inside].sum() < inside.sum() and (~known & inside).any()


def test_a_views_photometry_samples_are_numpys_sparse_grid() -> None:
    # The frame, the middle of the view's bounds and the pixels left out (unknown, or in an
    # anchor's box), on the sparse grid of the fit, as numpy's slices of the whole grid's.
    from percept.perception.light.adaptation_kernels import view_samples
    from percept.perception.light.maintenance import box_mask

    rng = np.random.default_rng(9)
    height, width, step = 47, 61, 2
    ycc = rng.integers(0, 256, (height, width, 3), dtype=np.uint8)
    lower = rng.integers(0, 256, (height, width, 3), dtype=np.uint8)
    upper = rng.integers(0, 256, (height, width, 3), dtype=np.uint8)
    known = rng.random((height, width)) < 0.8
    boxes = np.array([[10.0, 6.0, 30.0, 20.0], [70.0, 50.0, 33.0, 41.0]])
    for s in (1, 3, 4):
        frame, middle, excluded = view_samples(ycc, boxes, step, known, lower, upper, s)
        boxed = box_mask(boxes, (height, width), step)
        expected = (lower[::s, ::s].astype(np.uint16) + upper[::s, ::s]) // 2
        assert np.array_equal(frame, ycc[::s, ::s]) and frame.flags.c_contiguous
        assert middle.dtype == np.float32 and np.array_equal(middle, expected.astype(np.float32))
        assert np.array_equal(excluded, ~known[::s, ::s] | boxed[::s, ::s])
        assert boxed[::s, ::s].any() and (~known[::s, ::s] & ~boxed[::s, ::s]).any()


def test_marker_grey_levels_are_cv2_remaps() -> None:
    # The edge fit and the reading sample grey levels as they did with cv2.remap: the same
    # corners and readings. OpenCV rounds its float32 sums in its own order: a level may differ
    # by one where a sum falls within float32 rounding of a half.
    from percept.perception.landmarks.detection.quads_kernels import bilinear

    rng = np.random.default_rng(3)
    gray = rng.integers(0, 256, (60, 70)).astype(np.uint8)
    points = rng.uniform(-3.0, 73.0, (20000, 2)).astype(np.float32)
    points[:5000] = np.round(points[:5000] * 64) / 64  # on the grid of halves and quarters
    expected = cv2.remap(
        gray,
        points[:, :1].T.copy(),
        points[:, 1:].T.copy(),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    ).ravel()
    levels = np.array([bilinear(gray, float(x), float(y)) for x, y in points])
    differ = levels != expected
    assert np.abs(levels - expected).max() <= 1
    assert differ.sum() <= 5, differ.sum()


@pytest.mark.parametrize("n", [1, 2, 15, 16, 17, 650, 651])
def test_median_is_numpys_to_the_bit(n: int) -> None:
    # Residuals of whole grey levels repeat: ties, runs of one value and sorted input included.
    rng = np.random.default_rng(n)
    cases = [
        rng.normal(0.0, 3.0, n),
        np.round(rng.normal(0.0, 3.0, n)),
        np.full(n, 5.0),
        np.sort(rng.uniform(0.0, 1.0, n)),
        np.sort(rng.uniform(0.0, 1.0, n))[::-1].copy(),
        rng.integers(0, 3, n).astype(float),
    ]
    for values in cases:
        scratch = values.copy()
        assert median(scratch, n) == np.median(values)
        assert sorted(scratch.tolist()) == sorted(values.tolist())  # reordered, nothing lost


@pytest.mark.parametrize("step", [1, 3, 6])
def test_share_outside_is_numpys_mean_on_the_sparse_grid(step: int) -> None:
    rng = np.random.default_rng(step)
    mask = (rng.random((144, 176)) < 0.2).astype(np.uint8)
    excluded = np.zeros(mask.shape, bool)
    excluded[20:90, 30:120] = True
    outside = ~excluded[::step, ::step]
    assert share_outside(mask, excluded, step) == mask[::step, ::step][outside].mean()
    assert share_outside(mask, np.ones(mask.shape, bool), step) == 0.0


def test_noise_is_measured_through_a_pictures_edges() -> None:
    from percept.perception.landmarks.detection.noise_kernels import noise_sigma
    from percept.perception.warm import marker_card

    rng = np.random.default_rng(5)
    # In mid greys, so that no noise is clipped away at black or white.
    card = cv2.resize(marker_card(), (640, 480), interpolation=cv2.INTER_AREA) // 2 + 64
    assert noise_sigma(card, 8) < 1.0  # a sharp tag's edges are not noise
    for sigma in (2.0, 6.0, 10.0):
        noisy = np.clip(card + rng.normal(0.0, sigma, card.shape), 0, 255).astype(np.uint8)
        assert abs(noise_sigma(noisy, 8) - sigma) < 0.15 * sigma + 0.5, sigma
    assert noise_sigma(card[:2], 8) == noise_sigma(card[:, :2], 8) == 0.0


@pytest.mark.parametrize(("step", "frame"), [(1, 10), (2, 10), (1, 60), (2, 60)])
def test_the_one_call_segmentation_is_the_steps_it_composes(step: int, frame: int) -> None:
    """What the pipeline calls once a frame (regions, each pixel's class, the split) gives, to
    the bit, what the three steps give one after the other: with colour models taken from the
    regions of another frame (so that they compete for the pixels) and without models."""
    scene = busy_scene(176, 144, 120)  # (the objects move across each other from frame 12)
    background = scene.background.astype(int)

    def grid(t: int) -> tuple[np.ndarray, np.ndarray]:
        image = scene.render(t, noise=False)
        mask = (np.abs(image.astype(int) - background).max(axis=2) > 0).astype(np.uint8)
        return np.ascontiguousarray(mask[::step, ::step]), to_ycrcb(image)[::step, ::step].copy()

    params, min_region, min_split = SplitParams(), 5 * step**2, 8 * step**2
    segment = Segmenter(MARGINALS, min_region, params, min_split, step)
    earlier = find_regions(*grid(frame - 8), MARGINALS, min_region, step)
    model_boxes, models = earlier.boxes.astype(float), earlier.histograms
    mask, ycc = grid(frame)
    regions = find_regions(mask, ycc, MARGINALS, min_region, step)
    classes = classify(
        regions.boxes,
        regions.offsets,
        regions.pixel_bins,
        model_boxes,
        models,
        params.threshold,
        params.margin,
    )
    expected = split_regions(regions, classes, len(models), min_split)
    got = segment(mask, ycc, model_boxes, models)
    np.testing.assert_array_equal(got.classes, classes)
    assert (classes > 0).any() and len(models) >= 2
    if frame == 60:  # a moving object over a still one: their region is cut in two
        assert len(expected.counts) > len(regions)
    for name in ("boxes", "histograms", "counts", "regions"):
        np.testing.assert_array_equal(getattr(got.percepts, name), getattr(expected, name))
    for name in ("boxes", "histograms", "counts", "pixels", "pixel_region", "pixel_bins"):
        np.testing.assert_array_equal(getattr(got.regions, name), getattr(regions, name))
    whole = segment(mask, ycc, *segment.no_models)
    np.testing.assert_array_equal(whole.percepts.boxes, regions.boxes)
    np.testing.assert_array_equal(whole.percepts.histograms, regions.histograms)
    np.testing.assert_array_equal(whole.percepts.counts, regions.counts)
    assert not whole.classes.any()


def test_regions_on_a_rendered_frame_have_their_pixels_in_raster_order() -> None:
    scene = busy_scene(176, 144, 20)
    image = scene.render(10, noise=False)
    mask = (np.abs(image.astype(int) - scene.background.astype(int)).max(axis=2) > 0).astype(
        np.uint8
    )
    ycc = to_ycrcb(image)
    regions = find_regions(mask, ycc, MARGINALS, 5)
    for r in range(len(regions)):
        own = regions.pixels[regions.members(r)]
        assert (np.diff(own) > 0).all()
        assert (regions.pixel_region[regions.members(r)] == r).all()
    np.testing.assert_array_equal(
        regions.pixel_bins, ycc.reshape(-1, 3)[regions.pixels] >> bin_shift(16)
    )


@pytest.mark.parametrize("seed", range(8))
def test_regions_are_labelled_as_opencvs_grana(seed: int) -> None:
    rng = np.random.default_rng(seed)
    # Even seeds: speckle of any density in sizes of all kinds; odd: ellipses and specks.
    height, width = int(rng.integers(1, 100)), int(rng.choice([8, 13, 64, 176, 31]))
    mask = (rng.random((height, width)) < rng.uniform(0.05, 0.7)).astype(np.uint8)
    if seed % 2:
        mask = blobs(seed, width, 90) | (rng.random((90, width)) < 0.03).astype(np.uint8)
        height = 90
    ycc = rng.integers(0, 256, (height, width, 3), dtype=np.uint8)
    min_pixels, step = int(rng.integers(1, 6)), 2
    regions = find_regions(mask, ycc, MARGINALS, min_pixels * step**2, step)

    n, labels, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(
        mask, 8, cv2.CV_32S, cv2.CCL_GRANA
    )
    np.testing.assert_array_equal(regions.labels, labels)
    kept = [label for label in range(1, n) if stats[label, 4] >= min_pixels]
    np.testing.assert_array_equal(regions.label_ids, kept)
    np.testing.assert_array_equal(regions.boxes, stats[kept, :4] * step)
    np.testing.assert_array_equal(regions.counts, stats[kept, 4] * step**2)
    pixels = [np.flatnonzero(labels == label) for label in kept]
    np.testing.assert_array_equal(regions.pixels, np.concatenate([[], *pixels]))
    np.testing.assert_array_equal(regions.pixel_region, np.repeat(range(len(kept)), stats[kept, 4]))
    np.testing.assert_array_equal(
        regions.pixel_bins, ycc.reshape(-1, 3)[regions.pixels] >> bin_shift(16)
    )
    for r, own in enumerate(pixels):
        for c in range(3):
            hist = np.bincount(ycc.reshape(-1, 3)[own, c] >> 4, minlength=16) / len(own)
            np.testing.assert_array_equal(regions.histograms[r, c], hist)
    assert len(kept) > 0


def test_regions_of_isolated_pixels_are_every_foreground_pixel() -> None:
    # The most labels a mask can start: one at every other pixel of every other row.
    mask = np.zeros((9, 32), np.uint8)
    mask[::2, ::2] = 1
    ycc = np.zeros((*mask.shape, 3), np.uint8)
    regions = find_regions(mask, ycc, MARGINALS, 1)
    n, labels = cv2.connectedComponentsWithAlgorithm(mask, 8, cv2.CV_32S, cv2.CCL_GRANA)
    np.testing.assert_array_equal(regions.labels, labels)
    np.testing.assert_array_equal(regions.pixels, np.flatnonzero(mask))
    assert len(regions) == n - 1 == 5 * 16


def cache_dir(env: dict[str, str]) -> str:
    """numba's cache folder in a fresh interpreter that imports the kernels with ``env``."""
    code = (
        "import percept.perception.compiled, numba.core.config as c, os\n"
        "print(os.environ['NUMBA_CACHE_DIR'], c.CACHE_DIR, sep='\\n')\n"
    )
    base = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    out = subprocess.run(
        [sys.executable, "-c", code],
        env={**base, **env},
        capture_output=True,
        encoding="utf-8",
        check=True,
    )
    told, used = out.stdout.split()
    assert told == used
    return used


def test_fresh_samples_are_those_of_the_quiet_mask_with_the_boxes_cut_out() -> None:
    # The samples of unknown cells, quiet where OpenCV's closed still mask is not 0 (the kernel
    # tests the motion at those pixels only) outside the anchors' boxes, against the mask made
    # as Perception._learn made it (boxes reaching past the image, of no size, and starting
    # left of and above it).
    from percept.perception.view.learning_kernels import fresh_samples

    rng = np.random.default_rng(11)
    height, width, cells = 48, 64, 500
    nearest = rng.integers(-1, cells, (height, width)).astype(np.int32)
    seen = rng.random((height, width)) < 0.6
    known = rng.random(cells) < 0.3
    ycc = rng.integers(0, 256, (height, width, 3), dtype=np.uint8)
    previous = ycc.copy()
    changed = rng.random((height, width)) < 0.1  # specks, which the close removes
    changed[10:30, 25:45] = True  # and a body that moved
    previous[changed] = rng.integers(0, 256, (int(changed.sum()), 3), dtype=np.uint8)
    upper = rng.integers(0, 30, (height, width, 3), dtype=np.uint8)
    still = cv2.inRange(cv2.absdiff(ycc, previous), np.zeros_like(upper), upper)
    still = cv2.morphologyEx(still, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    boxes = np.array(
        [[-3.5, -2.2, 10.3, 8.9], [50.7, 40.1, 30.0, 20.0], [20.0, 20.0, 0.0, 0.0],
         [5.2, 30.9, 12.4, 3.3], [-9.0, 10.0, 4.0, 5.0]]
    )  # fmt: skip
    flat, values, calm = fresh_samples(nearest, ycc, previous, upper, 3, boxes, seen, known)
    quiet = still != 0
    for left, top, w, h in boxes.tolist():
        x0, y0 = max(int(left), 0), max(int(top), 0)
        quiet[y0 : max(int(top + h) + 1, y0), x0 : max(int(left + w) + 1, x0)] = False
    r, c = np.nonzero(~seen)
    take = (nearest[r, c] >= 0) & ~known[np.maximum(nearest[r, c], 0)]
    r, c = r[take], c[take]
    assert np.array_equal(flat, nearest[r, c])
    assert np.array_equal(values, ycc[r, c])
    assert np.array_equal(calm, quiet[r, c])
    assert calm.any() and not calm.all() and len(flat) > 100
    assert ((still[r, c] != 0) & ~calm).any()  # some only for a box
    assert (still[r, c] == 0).any()  # some for the motion


@pytest.mark.parametrize("size", [76800, 101])
def test_unseen_pixels_are_numpys_flatnonzero(size: int) -> None:
    # Nearly all True, as a frame's known view is: most words of eight are all True, some have
    # one False (whose word differs from all True only in its last bits), and a tail.
    rng = np.random.default_rng(size)
    seen = rng.random(size) > 0.002
    seen[8:16] = [True] * 7 + [False]
    seen[16:24] = [False] + [True] * 7
    assert np.array_equal(unseen(seen), np.flatnonzero(~seen))
    assert len(unseen(np.ones(size, bool))) == 0


@pytest.mark.parametrize("size", [1, 2, 3, 4, 5])
def test_motion_in_boxes_is_opencvs_closed_still_mask(size: int) -> None:
    # Frames where parts changed, boxes inside, across and outside the image: the count from
    # the two frames is the count on OpenCV's whole mask (inRange of absdiff, MORPH_CLOSE),
    # and so is the mask at single pixels.
    from percept.perception.tracking.motion_kernels import (
        MOST,
        moved_fraction,
        moved_in_boxes,
        still_at,
    )

    rng = np.random.default_rng(size)
    answered = answered_wide = 0
    for trial in range(60):
        wide = trial % 2 == 1  # boxes wider than 64 pixels: rows of several words
        h, w = (rng.integers(40, 90), 300) if wide else rng.integers(8, 90, 2)
        current = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        previous = current.copy()
        changed = rng.random((h, w)) < rng.random() * 0.6
        previous[changed] = rng.integers(0, 256, (int(changed.sum()), 3), dtype=np.uint8)
        upper = rng.integers(0, 40, (h, w, 3), dtype=np.uint8)
        still = cv2.inRange(cv2.absdiff(current, previous), np.zeros_like(upper), upper)
        if size > 1:
            still = cv2.morphologyEx(still, cv2.MORPH_CLOSE, np.ones((size, size), np.uint8))
        n = int(rng.integers(1, 5))
        if wide:
            sides = rng.uniform([0.3, 0.0], [0.7, 0.1], (n, 2)) * [w, h]
            corners = rng.uniform([-0.1, -0.1], [0.3, 1.0], (n, 2)) * [w, h]
        else:
            sides = rng.uniform(0, 0.3, (n, 2)) * [w, h]
            corners = rng.uniform(-0.1, 1.0, (n, 2)) * [w, h]
        boxes = np.column_stack([corners, sides])
        pixels = zip(rng.integers(0, h, 20).tolist(), rng.integers(0, w, 20).tolist(), strict=True)
        for y, x in pixels:
            assert still_at(current, previous, upper, y, x, size) == (still[y, x] != 0)
        expected = moved_fraction(still, boxes)
        x0, y0 = np.maximum(boxes[:, :2].astype(int), 0).T
        x1 = np.minimum(np.ceil(boxes[:, 0] + boxes[:, 2]), w).astype(int)
        y1 = np.minimum(np.ceil(boxes[:, 1] + boxes[:, 3]), h).astype(int)
        covered = 0
        for i in range(n):
            empty = x1[i] <= x0[i] or y1[i] <= y0[i]
            inside = still[y0[i] : y1[i], x0[i] : x1[i]]
            assert expected[i] == (0.0 if empty else float((inside == 0).mean()))
            pad = 2 * (size // 2) if size > 1 else 0
            width = min(x1[i] + pad, w) - max(x0[i] - pad, 0)
            height = min(y1[i] + pad, h) - max(y0[i] - pad, 0)
            covered += 0 if empty else width * height
        got = moved_in_boxes(current, previous, upper, boxes, size, MOST)
        if 4 * covered > h * w:  # the whole mask costs less: the caller makes it
            assert len(got) == 0
            wider = moved_in_boxes(current, previous, upper, boxes, size, 1.0)
            if covered <= h * w:  # up to the whole image when asked (overlaps counted twice)
                np.testing.assert_array_equal(wider, expected)
            else:
                assert len(wider) == 0
        else:
            np.testing.assert_array_equal(got, expected)
            answered += 1
            answered_wide += wide
    assert answered >= 20 and answered_wide >= 5
    # Half the image in one box: beyond a quarter, within the whole.
    half = np.array([[0.0, 0.0, w / 2, h]])
    assert len(moved_in_boxes(current, previous, upper, half, size, MOST)) == 0
    np.testing.assert_array_equal(
        moved_in_boxes(current, previous, upper, half, size, 1.0), moved_fraction(still, half)
    )


def turns(rng: np.random.Generator, w: int, h: int) -> list[np.ndarray]:
    """Homographies between a frame's pixels and the previous one's: small turns of a head (a
    few pixels, a little rotation and perspective) and one whose horizon crosses the image."""
    out = []
    for _ in range(4):
        shift = rng.uniform(-0.1, 0.1, 2) * [w, h]
        H = np.eye(3) + rng.normal(0, [[0.01, 0.01, 0], [0.01, 0.01, 0], [1e-4, 1e-4, 0]])
        H[:2, 2] += shift
        out.append(H)
    out.append(np.array([[1.0, 0.0, 2.0], [0.0, 1.0, 1.0], [0.0, 2.0 / h, -0.5]]))
    return out


def fixed_point_warp(previous: np.ndarray, current: np.ndarray, inverse: np.ndarray) -> np.ndarray:
    """The warp of :mod:`percept.perception.tracking.warp_kernels` in numpy, the same arithmetic
    written out over the whole image."""
    h, w = current.shape[:2]
    y, x = np.mgrid[0:h, 0:w].astype(float)
    i = inverse
    weight = i[2, 0] * x + (i[2, 1] * y + i[2, 2])
    with np.errstate(divide="ignore", invalid="ignore"):
        sx = (i[0, 0] * x + (i[0, 1] * y + i[0, 2])) / weight
        sy = (i[1, 0] * x + (i[1, 1] * y + i[1, 2])) / weight
    seen = (weight > 0) & (sx > -1) & (sy > -1) & (sx < w) & (sy < h)
    X = np.where(seen, ((np.where(seen, sx, 0) + 1) * 32 + 0.5).astype(np.int64) - 32, -32)
    Y = np.where(seen, ((np.where(seen, sy, 0) + 1) * 32 + 0.5).astype(np.int64) - 32, -32)
    ix, iy, ax, ay = X >> 5, Y >> 5, (X & 31)[..., None], (Y & 31)[..., None]
    seen &= (ix >= 0) & (ix < w - 1) & (iy >= 0) & (iy < h - 1)
    ix, iy = np.where(seen, ix, 0), np.where(seen, iy, 0)
    p = previous.astype(np.int64)
    value = (
        (32 - ax) * (32 - ay) * p[iy, ix]
        + ax * (32 - ay) * p[iy, ix + 1]
        + (32 - ax) * ay * p[iy + 1, ix]
        + ax * ay * p[iy + 1, ix + 1]
    )
    return np.where(seen[..., None], (value + 512) >> 10, current).astype(np.uint8)


def test_warp_is_the_fixed_point_bilinear_written_in_numpy() -> None:
    from percept.perception.tracking.warp_kernels import warp_all

    rng = np.random.default_rng(3)
    for h, w in ((48, 64), (37, 53), (240, 320)):
        previous = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        current = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        for H in turns(rng, w, h):
            inverse = np.linalg.inv(H)
            out = np.empty_like(current)
            warp_all(previous, current, inverse, out)
            expected = fixed_point_warp(previous, current, inverse)
            assert np.array_equal(out, expected)
            # Some pixels from the previous frame, some (what it did not see) the current's.
            assert 0 < np.count_nonzero(np.all(out == current, axis=2)) < h * w


def test_warp_is_within_a_grey_level_or_two_of_opencvs_on_a_smooth_image() -> None:
    # OpenCV 5 interpolates in float32 and mixes the current frame into pixels at the previous
    # frame's edge; away from that edge a smooth frame (gradients of up to 5 levels a pixel)
    # warped here is within two levels of it, and mostly equal.
    from percept.perception.tracking.warp_kernels import warp_all

    rng = np.random.default_rng(4)
    h, w = 120, 160
    y, x = np.mgrid[0:h, 0:w]
    previous = np.dstack([x * 1.5, 128 + 60 * np.sin(y / 9.0), (x + y) * 0.8]).astype(np.uint8)
    current = np.zeros_like(previous)
    for H in turns(rng, w, h)[:4]:
        out = np.empty_like(current)
        warp_all(previous, current, np.linalg.inv(H), out)
        opencv = cv2.cvtColor(current, cv2.COLOR_BGR2BGRA)
        cv2.warpPerspective(
            cv2.cvtColor(previous, cv2.COLOR_BGR2BGRA), H, (w, h), dst=opencv,
            flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_TRANSPARENT,
        )  # fmt: skip
        # Pixels whose point lies at least a pixel inside the previous frame.
        inner = np.zeros((h, w), np.uint8)
        inner[1:-2, 1:-2] = 1
        inner = cv2.warpPerspective(inner, H, (w, h), flags=cv2.INTER_NEAREST) > 0
        diff = np.abs(out.astype(int) - opencv[..., :3])[inner]
        assert inner.sum() > h * w / 2
        assert diff.max() <= 2 and (diff == 0).mean() > 0.8


@pytest.mark.parametrize("size", [1, 3, 4])
def test_motion_after_a_turn_reads_only_what_it_brings_into_the_view(size: int) -> None:
    # The motion of a turned head brings the previous frame into the view only in the boxes and
    # around the pixels asked about: what it answers there is what the whole warp and OpenCV's
    # whole closed mask give.
    from percept.perception.tracking.motion import Motion, opening_kernel
    from percept.perception.tracking.motion_kernels import moved_fraction, still_at
    from percept.perception.tracking.warp_kernels import warp_all

    rng = np.random.default_rng(size)
    answered = 0
    for _ in range(12):
        h, w = (int(v) for v in rng.integers(40, 120, 2))
        base = cv2.resize(rng.integers(0, 256, (h // 8 + 2, w // 8 + 2, 3), dtype=np.uint8), (w, h))
        H = turns(rng, w, h)[int(rng.integers(0, 4))]
        current = base.copy()
        warp_all(base, base, np.linalg.inv(H), current)  # the previous view turned
        current[h // 3 : h // 2, w // 4 : w // 2] = (200, 30, 90)  # and something moved
        upper = rng.integers(5, 30, (h, w, 3), dtype=np.uint8)
        bounds = (np.zeros_like(upper), upper)
        in_view = np.empty_like(current)
        warp_all(base, current, np.linalg.inv(H), in_view)
        still = cv2.inRange(cv2.absdiff(current, in_view), bounds[0], upper)
        kernel = opening_kernel(size)
        if kernel is not None:
            still = cv2.morphologyEx(still, cv2.MORPH_CLOSE, kernel)
        boxes = np.column_stack(
            [rng.uniform(-0.1, 0.9, (3, 2)) * [w, h], rng.uniform(0.05, 0.25, (3, 2)) * [w, h]]
        )
        got = Motion(current, base, bounds, kernel, 1, H).fraction(boxes)
        np.testing.assert_array_equal(got, moved_fraction(still, boxes))
        seen = rng.random((h, w)) > 0.02
        motion = Motion(current, base, bounds, kernel, 1, H)
        previous, upper_, square = motion.per_pixel(seen)
        for i in np.flatnonzero(~seen).tolist():
            y, x = divmod(i, w)
            assert still_at(current, previous, upper_, y, x, square) == (still[y, x] != 0)
        assert np.array_equal(motion.still(), still)  # the whole mask after the pixels
        answered += 1
    assert answered == 12


def test_compiled_code_is_cached_in_the_users_cache_folder(tmp_path: Path) -> None:
    from percept.perception.compiled import sources_digest

    digest = sources_digest()
    assert len(digest) == 16 and int(digest, 16) >= 0
    cached = tmp_path / "percept" / "numba" / digest
    assert cache_dir({"XDG_CACHE_HOME": str(tmp_path)}) == str(cached)
    home = tmp_path / "home"
    expected = str(home / ".cache" / "percept" / "numba" / digest)
    assert cache_dir({"HOME": str(home)}) == expected
    assert cache_dir({"HOME": str(home), "XDG_CACHE_HOME": "relative/cache"}) == expected
    assert cache_dir({"NUMBA_CACHE_DIR": str(tmp_path / "mine")}) == str(tmp_path / "mine")


def test_the_cache_folder_changes_with_any_kernels_source(tmp_path: Path) -> None:
    # numba checks a cached kernel against its own file only: a kernel it calls from another
    # file (say the border rule of compiled/boxes_kernels.py) changing must change the folder.
    import shutil

    from percept import perception
    from percept.perception.compiled import sources_digest

    copy = tmp_path / "perception"
    shutil.copytree(Path(perception.__file__).parent, copy, ignore=shutil.ignore_patterns("__py*"))
    assert sources_digest(copy) == sources_digest()
    (copy / "pipeline.py").write_text("")  # no kernel: the compiled code stays valid
    assert sources_digest(copy) == sources_digest()
    boxes = copy / "compiled" / "boxes_kernels.py"
    boxes.write_text(boxes.read_text().replace("left < 1", "left < 0"))
    changed = sources_digest(copy)
    assert changed != sources_digest()
    (copy / "segmentation" / "new_kernels.py").write_text("")
    assert sources_digest(copy) not in (changed, sources_digest())


def _rim(points: int) -> np.ndarray:
    angles = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    return 0.5 * np.column_stack([np.cos(angles), np.sin(angles)])


def test_frusta_rims_are_circles_of_the_footprint_and_the_top() -> None:
    rim = _rim(16)
    params = np.array([[0.3, -0.2, 0.1, 0.25, 0.5], [1.0, 2.0, 0.4, 0.1, 1.0], [0, 0, 1, 1, 0]])
    points = frusta(params, rim)
    assert points.shape == (3, 32, 3)
    for (x, y, d, h, k), solid in zip(params, points, strict=True):
        bottom, top = solid[:16], solid[16:]
        assert np.allclose(bottom[:, 2], 0.0) and np.allclose(top[:, 2], h)
        for ring, diameter in ((bottom, d), (top, k * d)):
            offset = ring[:, :2] - (x, y)
            assert np.allclose(np.hypot(*offset.T), diameter / 2, atol=1e-12)
            assert np.allclose(offset, diameter * rim, atol=1e-12)  # in the rim's order


def test_a_balls_outline_is_where_the_lines_of_sight_touch_it() -> None:
    rim = _rim(32)
    camera = np.array([0.1, -0.3, 0.8])
    params = np.array([[1.0, 0.5, 0.2], [0.1, -0.3, 0.3], [0.1, -0.2, 2.0]])
    outline = balls(params, *camera, rim)
    assert outline.shape == (3, 32, 3)
    for (x, y, d), points in zip(params[:2], outline[:2], strict=True):
        centre = np.array([x, y, d / 2])
        radius, sight = points - centre, points - camera
        assert np.allclose(np.linalg.norm(radius, axis=1), d / 2)  # on the sphere
        assert np.allclose(np.einsum("ij,ij->i", radius, sight), 0.0, atol=1e-12)  # tangent
        # around the circle of contact (the second ball straight below the camera)
        spread = np.linalg.norm(points - points.mean(axis=0), axis=1)
        assert spread.min() > 0.05 * d and np.ptp(spread) < 1e-12
    assert np.isnan(outline[2]).all()  # the camera inside the ball


def test_warm_up_compiles_each_kernel_for_the_types_of_real_frames() -> None:
    # Every kernel compiled (or loaded) by the warm-up, before the first frame of a robot; and
    # none compiled again later for other argument types (say, an array that happens to be
    # contiguous), on a robot's frame: each has the signatures of the warm-up after frames of
    # several sizes, a moving head and a marker picture.
    code = (
        "from percept.perception.warm import warm_up\n"
        "warm_up()\n"
        "from percept.perception.tracking import anchors_kernels as anchors\n"
        "from percept.perception.tracking import kalman_kernels as kalman\n"
        "from percept.perception.tracking import motion_kernels as motion\n"
        "from percept.perception.tracking import warp_kernels as warp\n"
        "from percept.perception.tracking.permanence import memory_kernels as memory\n"
        "from percept.perception.tracking import update_kernels as update\n"
        "from percept.perception.segmentation import grid_kernels as grid\n"
        "from percept.perception.segmentation import percepts_kernels as percepts\n"
        "from percept.perception.segmentation import segment_kernels as segment\n"
        "from percept.perception.light import adaptation_kernels as adaptation\n"
        "from percept.perception.light import foreground_kernels as foreground\n"
        "from percept.perception.light import ghosts_kernels as ghosts\n"
        "from percept.perception.light import maintenance_kernels as maintenance\n"
        "from percept.perception.light import masks_kernels as masks\n"
        "from percept.perception.light.photometry import photometric_kernels as photometric\n"
        "from percept.perception.view import alignment_kernels as alignment\n"
        "from percept.perception.view import bounds_kernels as bounds\n"
        "from percept.perception.view import cells_kernels as cells\n"
        "from percept.perception.view.map import directions_kernels as directions\n"
        "from percept.perception.view import ghosts_kernels as view_ghosts\n"
        "from percept.perception.view import learning_kernels as learning\n"
        "from percept.perception.landmarks.detection import noise_kernels as noise\n"
        "from percept.perception.landmarks.detection import quads_kernels as quads\n"
        "from percept.perception.features import solids_kernels as solids\n"
        "from percept.perception.features import images_kernels as images\n"
        "from percept.perception.features import newton_kernels as newton\n"
        "kernels = (grid.every_step, segment.segment, percepts.merge_groups,\n"
        "           directions.ray_directions, directions.cells_of, learning.fresh_samples,\n"
        "           learning.accumulate, learning.mark_cells, bounds.bounds_in_view,\n"
        "           alignment.alignment_images,\n"
        "           quads.fit_quads,\n"
        "           quads.cell_levels, quads.repeats, noise.noise_sigma, kalman.predict,\n"
        "           kalman.boxes, kalman.warp, anchors.blend,\n"
        "           anchors.may_double, update.track,\n"
        "           motion.moved_fraction, motion.moved_in_boxes,\n"
        "           warp.warp_boxes, warp.warp_near, warp.warp_all,\n"
        "           photometric.fit_photometry, photometric.affine_map, ghosts.ghost_regions,\n"
        "           masks.box_mask, masks.mark, adaptation.light_frame, adaptation.light_after,\n"
        "           maintenance.follow_quiet, memory.covered,\n"
        "           memory.hidden_fraction, memory.touches_border, memory.feet,\n"
        "           memory.reaches,\n"
        "           cells.cell_bounds, cells.tiles, learning.settle, memory.sight,\n"
        "           memory.inside_fraction,\n"
        "           foreground.light_foreground, solids.frusta, solids.balls,\n"
        "           images.outline_images, newton.solid_newton, view_ghosts.map_in_view,\n"
        "           adaptation.view_samples)\n"
        "print([len(k.signatures) for k in kernels])\n"
        "from percept.perception.evaluation.synthetic import busy_scene\n"
        "from percept.perception.params import PerceptionParams\n"
        "from percept.perception.pipeline import Perception\n"
        "for w, h in ((640, 480), (100, 75)):\n"
        "    scene = busy_scene(w, h, 30)\n"
        "    p = Perception(PerceptionParams(), w, h)\n"
        "    p.calibrate(scene.empty(30))\n"
        "    for f in range(30):\n"
        "        p.process(scene.render(f), f / 25)\n"
        "import numpy as np\n"
        "from tests.support.moving_head import PanningRobot\n"
        "robot = PanningRobot(((0.0, -0.3), (1.0, 0.3), (2.0, 0.0)), None, (320, 240))\n"
        "p = Perception(PerceptionParams(), 320, 240, robot.camera)\n"
        "robot.calibrated(p, np.linspace(0.0, 1.0, 30))\n"
        "for t in np.arange(1.0, 2.0, 0.1).tolist():\n"
        "    p.process(robot.frames(np.array([t]))[0], t, robot.pose(t))\n"
        "from percept.perception.landmarks.detection.detector import MarkerDetector\n"
        "from percept.perception.warm import marker_card\n"
        "import cv2\n"
        "detector = MarkerDetector()\n"
        "found = detector.detect(cv2.cvtColor(marker_card(), cv2.COLOR_GRAY2BGR))\n"
        "window = detector.detect_prepared(marker_card(), (37, 41, 130, 133))\n"
        "assert [m.id for m in found] == [m.id for m in window] == [0]\n"
        "print([len(k.signatures) for k in kernels])\n"
    )
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, encoding="utf-8", check=True, env=env
    )
    warmed, after = (json.loads(line) for line in out.stdout.split("\n")[-3:-1])
    # One signature each from a warm cache; on a cold one, a kernel called from another compiled
    # one gets a signature for that caller too (outline_images from solid_newton's fits). The
    # kernels only compiled ones call (the association and correction, in the anchors' update;
    # the labelling and the colour split, in the frame's segmentation) are not listed: from a
    # warm cache they have none.
    assert len(warmed) == 50 and min(warmed) >= 1
    assert after == warmed


def _kernel_in_copy(root: Path, cache: Path) -> dict[str, int]:
    """In a fresh interpreter that imports percept's kernels from a copy of the package under
    ``root`` and caches in ``cache``: one kernel's cache hits and misses on its first call."""
    code = (
        "import json, percept.perception.compiled.boxes_kernels as b\n"
        f"assert b.__file__.startswith({str(root)!r}), b.__file__\n"
        "b.pixel_span(0.5, 0.5, 3.0, 2.0, 10, 10)\n"
        "s = b.pixel_span.stats\n"
        "print(json.dumps({'hits': sum(s.cache_hits.values()),"
        " 'misses': sum(s.cache_misses.values())}))\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("XDG_CACHE_HOME", "PYTHONPATH")}
    env.update(NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(root))
    out = subprocess.run(
        [sys.executable, "-c", code],
        env=env,
        cwd=root,
        capture_output=True,
        encoding="utf-8",
        check=True,
    )
    return json.loads(out.stdout)


def test_a_second_install_location_loads_the_code_the_first_compiled(tmp_path: Path) -> None:
    # numba files a kernel under a digest of its source folder's absolute path: each new venv
    # compiled everything again. Two copies of the package at two places share one compilation.
    import shutil

    from percept.perception import compiled

    for place in ("first", "second"):
        package = tmp_path / place / "percept"
        shutil.copytree(
            Path(compiled.__file__).parent,
            package / "perception" / "compiled",
            ignore=shutil.ignore_patterns("__py*"),
        )
        for folder in (package, package / "perception"):
            (folder / "__init__.py").write_text("")
    cache = tmp_path / "cache"
    assert _kernel_in_copy(tmp_path / "first", cache) == {"hits": 0, "misses": 1}
    assert _kernel_in_copy(tmp_path / "second", cache) == {"hits": 1, "misses": 0}


def test_a_kernel_loaded_from_the_cache_is_linked_from_its_bitcode(tmp_path: Path) -> None:
    # A loaded kernel's IR is parsed only when a new compilation links it (it was kept parsed,
    # 26 MB for the daemon's kernels): a function compiled later that calls it still works.
    code = (
        "import json, numba\n"
        "from percept.perception.compiled.boxes_kernels import pixel_span\n"
        "args = (0.5, 0.5, 3.0, 2.0, 10, 10)\n"
        "direct = pixel_span(*args)\n"
        "(library,) = [c.library for c in pixel_span.overloads.values()]\n"
        "parsed = library._shared_module is not None\n"
        "caller = numba.njit(lambda a, b, c, d, e, f: pixel_span(a, b, c, d, e, f)[2] + 1)\n"
        "print(json.dumps({'hits': sum(pixel_span.stats.cache_hits.values()),"
        " 'parsed': parsed, 'direct': direct, 'linked': caller(*args)}))\n"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    runs = [
        json.loads(
            subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, check=True, text=True
            ).stdout
        )
        for _ in range(2)
    ]
    compiled, loaded = runs
    assert compiled["hits"] == 0 and loaded["hits"] == 1
    assert not loaded["parsed"]
    assert loaded["direct"] == [0, 0, 4, 3]
    assert compiled["linked"] == loaded["linked"] == 5


def _seen_from_above() -> tuple[CameraModel, CameraPose]:
    """A 640x480 pinhole 0.5 m above the ground, looking 0.6 rad down and a little left."""
    camera = CameraModel.from_opening_angles(1.0, 0.8, 640, 480)
    return camera, CameraPose(R=rpy_matrix((0.0, 0.6, 0.1)), t=np.array([0.0, 0.0, 0.5]))


def _images_in_numpy(camera: CameraModel, pose: CameraPose, points: np.ndarray) -> np.ndarray:
    """(left, right, top, bottom, area) of point sets (n, m, 3) by the camera model's projection,
    numpy's reductions and OpenCV's convex hull: what :func:`outline_images` replaces."""
    uv = camera.project((points.reshape(-1, 3) - pose.t) @ pose.R).reshape(len(points), -1, 2)
    areas = [cv2.contourArea(cv2.convexHull(o.astype(np.float32))) for o in uv]
    return np.column_stack([uv.min(axis=1), uv.max(axis=1), areas])[:, [0, 2, 1, 3, 4]]


def test_outline_images_are_the_camera_models_boxes_and_opencvs_hull_areas() -> None:
    camera, pose = _seen_from_above()
    rng = np.random.default_rng(3)
    params = np.column_stack(
        [
            rng.uniform(0.4, 1.5, 300),
            rng.uniform(-0.5, 0.5, 300),
            rng.uniform(0.02, 0.2, 300),
            rng.uniform(0.02, 0.3, 300),
            rng.uniform(0.0, 1.0, 300),
        ]
    )
    params[:20, 4] = 0.0  # cones: the apex inside or outside the footprint's outline
    for points in (frusta(params, _rim(32)), balls(params[:, :3], *pose.t, _rim(32))):
        got = outline_images(points, pose.R, pose.t, camera.K, True)
        want = _images_in_numpy(camera, pose, points)
        assert np.abs(got[:, :4] - want[:, :4]).max() < 1e-9  # the same sums, in another order
        assert np.abs(got[:, 4] / want[:, 4] - 1.0).max() < 1e-12
        assert np.isnan(outline_images(points, pose.R, pose.t, camera.K, False)[:, 4]).all()
    behind = frusta(params[:3], _rim(8)) - [5.0, 0.0, 0.0]  # the camera is at x = 0
    assert np.isnan(outline_images(behind, pose.R, pose.t, camera.K, True)).all()


def test_hull_area_is_opencvs_with_repeated_and_collinear_points() -> None:
    rng = np.random.default_rng(5)
    for size in (3, 4, 10, 64):
        points = rng.integers(0, 6, (size, 2)).astype(float)  # many repeats and lines
        want = cv2.contourArea(cv2.convexHull(points.astype(np.float32)))
        assert hull_area(points[:, 0].copy(), points[:, 1].copy()) == pytest.approx(want)
    line = np.arange(5.0)
    assert hull_area(line, 2 * line) == 0.0


def test_compiled_box_fit_takes_the_steps_of_newtons_method_in_numpy() -> None:
    # The compiled fit against footprint._newton measuring with numpy and OpenCV: the same
    # frustum from the same start, to well under a micrometre; and the true one from a start
    # some centimetres off.
    camera, pose = _seen_from_above()
    rim, steps = _rim(32), (15, 1e-5, 1e-3, 1e-6, 0.0)
    for truth in (
        [0.9, 0.2, 0.08, 0.12, 1.0],
        [0.7, -0.1, 0.1, 0.05, 0.4],
        [1.2, 0.0, 0.2, 0.2, 0.0],
    ):
        k = truth[4]
        edges = _images_in_numpy(camera, pose, frusta(np.array([truth]), rim))[0, :4]
        start = np.array(truth[:4]) + np.array([0.03, -0.02, 0.02, 0.03])

        def box(q: np.ndarray, k: float = k) -> np.ndarray:
            params = np.column_stack([q, np.full(len(q), k)])
            return _images_in_numpy(camera, pose, frusta(params, rim))[:, :4]

        want = footprint._newton(box, edges, start, 15)
        found, got = solid_newton(
            BOX, edges, start, k, np.ones(4), np.ones(4), rim, pose.R, pose.t, camera.K, *steps
        )
        assert want is not None and found
        assert np.abs(got - want).max() < 1e-9
        assert np.abs(got - truth[:4]).max() < 1e-5
    # A start whose steps leave the ground's solids: no fit, as in numpy.
    start = np.array([-3.0, 0.0, 0.01, 0.01])
    found, _ = solid_newton(
        BOX, edges, start, 1.0, np.ones(4), np.ones(4), rim, pose.R, pose.t, camera.K, *steps
    )
    assert footprint._newton(box, edges, start, 15) is None and not found


def test_compiled_ball_fit_takes_the_steps_of_newtons_method_in_numpy() -> None:
    # Three unknowns, five measurements over their noise (least-squares steps), settled when a
    # step moves no measurement by a twentieth of its noise: as footprint._newton in numpy.
    camera, pose = _seen_from_above()
    rim, steps = _rim(32), (15, 1e-5, 1e-3, 1e-6, 0.05)
    sigma = np.array([0.29, 0.29, 0.29, 0.29, 4.0])
    for truth in ([0.9, 0.2, 0.08], [0.6, -0.15, 0.12], [1.3, 0.1, 0.3]):
        measured = _images_in_numpy(camera, pose, balls(np.array([truth]), *pose.t, rim))[0]
        target = (
            measured + np.array([0.2, -0.1, 0.1, 0.0, 9.0])
        ) / sigma  # a box and count of a lattice
        start = np.array(truth) + np.array([0.02, 0.01, -0.01])

        def ball(p: np.ndarray) -> np.ndarray:
            return _images_in_numpy(camera, pose, balls(p, *pose.t, rim)) / sigma

        want = footprint._newton(ball, target, start, 15, moved=0.05)
        found, got = solid_newton(
            BALL, target, start, 1.0, sigma, np.ones(5), rim, pose.R, pose.t, camera.K, *steps
        )
        assert want is not None and found
        assert np.abs(got - want).max() < 1e-9
        assert np.abs(got - truth).max() < 2e-3  # the measurements' offsets, in metres


def test_compiled_frustum_fit_takes_the_steps_of_newtons_method_in_numpy() -> None:
    # Five unknowns (the ratio k among them), the box and the area weighed as pixels: as
    # footprint._newton with its clip, k clipped into [0, 1] (then that is the answer), and the
    # same starts that fail.
    camera, pose = _seen_from_above()
    rim, steps = _rim(32), (15, 1e-5, 1e-3, 1e-6, 0.0)
    outcomes = []
    for truth, more, k0 in (
        ([0.8, 0.1, 0.1, 0.12, 0.3], 0.0, 0.5),
        ([0.9, -0.1, 0.08, 0.1, 0.9], 40.0, 0.5),  # more area than any k in [0, 1] gives
        ([0.9, -0.1, 0.08, 0.1, 0.9], 40.0, 0.0),
        ([0.7, 0.0, 0.1, 0.1, 0.6], 0.0, 0.0),
    ):
        target = _images_in_numpy(camera, pose, frusta(np.array([truth]), rim))[0]
        target[4] += more
        weights = np.array([1.0, 1.0, 1.0, 1.0, 1.0 / np.sqrt(target[4])])

        def measure(p: np.ndarray) -> np.ndarray:
            return _images_in_numpy(camera, pose, frusta(p, rim))

        def clip(p: np.ndarray) -> bool:
            k = min(max(p[4], 0.0), 1.0)
            changed, p[4] = k != p[4], k
            return bool(changed)

        start = np.array([*truth[:4], k0]) + np.array([0.02, 0.01, 0.01, -0.01, 0.0])
        want = footprint._newton(measure, target, start, 15, weights, clip)
        found, got = solid_newton(
            FRUSTUM, target, start, 1.0, np.ones(5), weights, rim, pose.R, pose.t, camera.K, *steps
        )
        assert found == (want is not None)
        if found:
            assert np.abs(got - want).max() < 1e-9
            outcomes.append("clipped" if got[4] == 1.0 else "fitted")
        else:
            outcomes.append("none")
    assert outcomes == ["fitted", "none", "clipped", "none"]


def test_solve4_is_numpys_solve_and_least_squares_without_a_pivot() -> None:
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(4, 4)), rng.normal(size=4)
    assert np.allclose(solve4(a, b), np.linalg.solve(a, b), rtol=1e-12, atol=1e-12)
    a[:, 2] = 0.0  # one parameter moves no edge
    assert np.allclose(solve4(a, b), np.linalg.lstsq(a, b, rcond=None)[0])


def _rank_deficient(rng: np.random.Generator, m: int, n: int, kind: str) -> np.ndarray:
    """An (m, n) matrix of less than full rank: a zero column (a parameter that moves no
    measurement), a column repeated, or a product of two of rank 1 to min(m, n) - 1."""
    a = rng.normal(size=(m, n))
    if kind == "zero column":
        a[:, rng.integers(n)] = 0.0
    elif kind == "repeated column":
        j, k = rng.choice(n, 2, replace=False)
        a[:, k] = a[:, j]
    else:
        r = int(rng.integers(1, min(m, n)))
        a = rng.normal(size=(m, r)) @ rng.normal(size=(r, n))
    return a


@pytest.mark.parametrize("shape", [(4, 4), (5, 3), (5, 5), (6, 5)])
def test_least_squares_is_numpys_lstsq(shape: tuple[int, int]) -> None:
    # The fits' systems: the box's 4x4, the ball's 5x3, the frustum's 5x5 (and one more row).
    # Full rank at scales from 1e-3 to 1e3, rank-deficient and zero: the minimum-norm solution
    # with numpy's default rcond, as numpy's SVD gives it, to 1e-10 of its size.
    m, n = shape
    rcond = np.finfo(float).eps * max(m, n)
    rng = np.random.default_rng(m * 10 + n)
    cases = [rng.normal(size=shape) * 10.0 ** rng.uniform(-3, 3) for _ in range(100)]
    for kind in ("zero column", "repeated column", "product"):
        cases += [_rank_deficient(rng, m, n, kind) for _ in range(100)]
    for a in cases:
        b = rng.normal(size=m)
        want = np.linalg.lstsq(a, b, rcond=rcond)[0]
        got = least_squares(a, b, rcond)
        assert np.abs(got - want).max() <= 1e-10 * np.abs(want).max()
    zero = np.zeros(shape)
    assert (least_squares(zero, rng.normal(size=m), rcond) == 0.0).all()
    # The rank by numpy's rule: singular values at most rcond times the largest are dropped.
    a = np.diag([1.0, 1e-3, 1e-6, 1e-9])
    b = np.ones(4)
    for cut in (1e-2, 1e-4, 1e-7, 1e-10):
        assert np.allclose(least_squares(a, b, cut), np.linalg.lstsq(a, b, rcond=cut)[0])


#: What numba builds on scipy's BLAS and LAPACK bindings (``@`` on arrays too).
_SCIPY_BUILT = {"dot", "vdot", "inner", "matmul", "tensordot", "linalg"}


def test_no_kernel_calls_what_numba_builds_on_scipy() -> None:
    # The onboard install has no scipy: a kernel that calls np.linalg, np.dot or ``@`` does
    # not compile there.
    import ast

    from percept.perception.compiled import kernel_sources

    for path in kernel_sources():
        for node in ast.walk(ast.parse(path.read_text())):
            calls = isinstance(node, ast.Attribute) and node.attr in _SCIPY_BUILT
            multiplies = isinstance(node, ast.BinOp | ast.AugAssign) and isinstance(
                node.op, ast.MatMult
            )
            assert not (calls or multiplies), f"{path.name}:{node.lineno}"


def test_the_least_squares_steps_compile_without_scipy(tmp_path: Path) -> None:
    # numba's np.linalg.lstsq did not compile with scipy hidden ("scipy 0.16+ is required for
    # linear algebra"); the fits' own does. An empty kernel cache, so it is compiled, not loaded.
    code = (
        "import sys\n"
        "sys.modules['scipy'] = None  # import scipy raises ImportError\n"
        "import numpy as np\n"
        "from percept.perception.features.newton_kernels import solve4\n"
        "a = np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 4.0]])\n"
        "print(solve4(a, np.array([2.0, 1.0, 2.0])).tolist())\n"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, encoding="utf-8", check=True, env=env
    )
    assert json.loads(out.stdout) == [1.0, 0.0, 0.5]  # no pivot: the least-norm solution
