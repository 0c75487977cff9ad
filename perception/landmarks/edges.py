"""Sub-pixel marker corners from straight lines fitted to the black square's four edges.

A corner found as a contour's vertex is good to a pixel; the square's edges are straight over
many pixels, so a line fitted to them is good to a small fraction of one, and two adjacent lines
cross at the corner. Each edge is sampled at a few points; at each, the grey levels along the
edge's normal (inside the black square to outside it) locate the edge where they rise, as the
centroid of that rise; a least-squares line through those points is the edge. The normal is
read no farther than most of one cell on either side, so the data cells inside the black border
and whatever lies beyond the white border stay out of it. All markers are done at once in
arrays, grey levels sampled bilinearly in OpenCV's pixel convention (the centre of the top-left
pixel at (0, 0)).
"""

from __future__ import annotations

import cv2
import numpy as np

SAMPLES = np.linspace(0.15, 0.85, 8)  # along each edge, away from the corners' rounding
STEPS = np.linspace(-1.0, 1.0, 17)  # along the normal, in units of the reach
REACH = 0.8  # cells of the marker either side of the edge
REACH_PIXELS = (1.0, 4.0)  # the reach's bounds in pixels: blur needs 1, clutter stops at 4
CHUNK = 1024  # cv2.remap's maps are at most 32767 wide: points go in rows of this many
NEXT, PREVIOUS = [1, 2, 3, 0], [3, 0, 1, 2]  # corners round a quad


def sample(gray: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bilinear grey levels of ``gray`` at ``points`` (..., 2) (x, y pixels), as float32 of
    shape ``points.shape[:-1]``; points outside take the nearest edge pixel's level."""
    flat = points.reshape(-1, 2).astype(np.float32)
    rows = -(-len(flat) // CHUNK)
    maps = np.zeros((rows * CHUNK, 2), np.float32)
    maps[: len(flat)] = flat
    levels = cv2.remap(
        gray,
        maps[:, 0].reshape(rows, CHUNK),
        maps[:, 1].reshape(rows, CHUNK),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return levels.ravel()[: len(flat)].astype(np.float32).reshape(points.shape[:-1])


def fit_edges(gray: np.ndarray, corners: np.ndarray, cells: int, passes: int = 2) -> np.ndarray:
    """Corners (N, 4, 2) of dark squares of ``cells`` cells a side moved onto the crossings of
    lines fitted to their edges in ``gray``, each of ``passes`` from the last one's corners (the
    second moves them by hundredths of a pixel); a corner that would move farther than a
    quarter of its square's side (or 2 px) keeps its place."""
    q = np.asarray(corners, dtype=float)
    if len(q) == 0:
        return q
    side = _length(q[:, NEXT] - q).mean(axis=1)
    reach = np.clip(REACH * side / cells, *REACH_PIXELS)
    offsets = STEPS[None, :] * reach[:, None]  # (N, L)
    middles = (offsets[:, 1:] + offsets[:, :-1]) / 2
    limit = np.maximum(2.0, 0.25 * side)[:, None]
    for _ in range(passes):
        start = q
        edge = q[:, NEXT] - start  # edge k runs from corner k to corner k + 1
        normal = edge[..., ::-1] * (1.0, -1.0) / _length(edge)[..., None]
        outward = ((start + edge / 2 - q.mean(axis=1, keepdims=True)) * normal).sum(-1)
        normal *= np.sign(outward)[..., None]
        on_edge = start[:, :, None] + SAMPLES[None, None, :, None] * edge[:, :, None]
        across = on_edge[:, :, :, None] + offsets[:, None, None, :, None] * normal[:, :, None, None]
        rise = np.maximum(np.diff(sample(gray, across), axis=-1), 0.0)  # (N, 4, S, L - 1)
        strength = rise.sum(axis=-1)
        shift = (rise * middles[:, None, None]).sum(axis=-1) / np.maximum(strength, 1e-6)
        points = on_edge + shift[..., None] * normal[:, :, None]
        # Points where the edge hardly rises (a highlight, an occluder) do not pull the line.
        middle = np.sort(strength, axis=-1)[..., len(SAMPLES) // 2, None]
        weight = (strength > 0.3 * middle).astype(float)
        centre, direction = _lines(points, weight)
        # corner k: where edges k - 1 and k cross
        crossing = _cross(centre[:, PREVIOUS], direction[:, PREVIOUS], centre, direction)
        moved = _length(crossing - q)
        keep = ~np.isfinite(crossing).all(axis=-1) | (moved > limit)
        q = np.where(keep[..., None], q, crossing)
    return q


def _length(v: np.ndarray) -> np.ndarray:
    return np.sqrt((v * v).sum(axis=-1))


def _lines(points: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares lines through ``points`` (..., S, 2): centres and unit directions
    (..., 2) (the principal axis of the points' scatter)."""
    total = np.maximum(weight.sum(axis=-1, keepdims=True), 1e-9)
    centre = (points * weight[..., None]).sum(axis=-2) / total
    d = points - centre[..., None, :]
    sxx = (weight * d[..., 0] ** 2).sum(-1)
    syy = (weight * d[..., 1] ** 2).sum(-1)
    sxy = (weight * d[..., 0] * d[..., 1]).sum(-1)
    angle = 0.5 * np.arctan2(2 * sxy, sxx - syy)
    return centre, np.stack([np.cos(angle), np.sin(angle)], axis=-1)


def _cross(c1: np.ndarray, d1: np.ndarray, c2: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Where the lines ``c1 + s d1`` and ``c2 + t d2`` cross (NaN where parallel)."""
    det = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
    gap = c2 - c1
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (gap[..., 0] * d2[..., 1] - gap[..., 1] * d2[..., 0]) / det
        return c1 + s[..., None] * d1
