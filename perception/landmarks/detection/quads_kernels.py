"""Marker quads' kernels: grey levels sampled under a quad's cells, and lines fitted to its edges.

percept's marker detector reads and fits some 20 quads a frame (:mod:`.decoding`,
:mod:`.edges`); written as numpy over all quads at once that was some 150 calls of
small arrays, 1.5 ms a 640x480 frame of ``bench/bench_markers.py``, here one call each. Grey
levels are sampled as ``cv2.remap`` samples them (bilinear, in float32, rounded to a grey level,
the nearest edge pixel's level outside the image), so the corners are those of the numpy version.
"""

from __future__ import annotations

import math

import numpy as np

from percept.perception.compiled import jit

NEXT = (1, 2, 3, 0)  # corners round a quad
PREVIOUS = (3, 0, 1, 2)


@jit
def bilinear(gray: np.ndarray, x: float, y: float) -> float:
    """The grey level of ``gray`` at ``(x, y)`` (pixels, the centre of the top-left pixel at
    (0, 0)) as OpenCV 5's ``cv2.remap`` gives it with ``INTER_LINEAR`` and
    ``BORDER_REPLICATE`` (its maps are float32)."""
    h, w = gray.shape
    xf, yf = np.float32(x), np.float32(y)
    x0, y0 = math.floor(xf), math.floor(yf)
    fx, fy = xf - np.float32(x0), yf - np.float32(y0)
    xa, xb = min(max(x0, 0), w - 1), min(max(x0 + 1, 0), w - 1)
    ya, yb = min(max(y0, 0), h - 1), min(max(y0 + 1, 0), h - 1)
    one = np.float32(1.0)
    top = (one - fx) * np.float32(gray[ya, xa]) + fx * np.float32(gray[ya, xb])
    bottom = (one - fx) * np.float32(gray[yb, xa]) + fx * np.float32(gray[yb, xb])
    return float(min(max(np.rint((one - fy) * top + fy * bottom), 0.0), 255.0))


@jit
def cell_levels(gray: np.ndarray, quads: np.ndarray, cells: int, within: np.ndarray) -> np.ndarray:
    """The mean grey level (N, cells, cells) of each cell of quads (N, 4, 2) (corners
    clockwise, the first at the cells' top-left) divided into ``cells`` by ``cells`` cells by
    their homography, read at the points ``within`` (parts of a cell) in both directions."""
    n, k = len(quads), len(within)
    out = np.zeros((n, cells, cells))
    for q in range(n):
        h = _square_to_quad(quads[q])
        for row in range(cells):
            for col in range(cells):
                total = 0.0
                for i in range(k):
                    v = (row + within[i]) / cells
                    for j in range(k):
                        u = (col + within[j]) / cells
                        z = h[6] * u + h[7] * v + 1.0
                        x = (h[0] * u + h[1] * v + h[2]) / z
                        y = (h[3] * u + h[4] * v + h[5]) / z
                        total += bilinear(gray, x, y)
                out[q, row, col] = total / (k * k)
    return out


@jit
def _square_to_quad(c: np.ndarray) -> np.ndarray:
    """The homography (a, b, c, d, e, f, g, h) taking the unit square's corners (0, 0), (1, 0),
    (1, 1), (0, 1) to the quad ``c`` (4, 2): ``x = (a u + b v + c) / (g u + h v + 1)``,
    ``y = (d u + e v + f) / (g u + h v + 1)`` (Heckbert's closed form)."""
    x0, y0, x1, y1 = c[0, 0], c[0, 1], c[1, 0], c[1, 1]
    x2, y2, x3, y3 = c[2, 0], c[2, 1], c[3, 0], c[3, 1]
    sx, sy = x0 - x1 + x2 - x3, y0 - y1 + y2 - y3
    dx1, dx2, dy1, dy2 = x1 - x2, x3 - x2, y1 - y2, y3 - y2
    det = dx1 * dy2 - dx2 * dy1
    g = (sx * dy2 - dx2 * sy) / det if det != 0.0 else 0.0
    h = (dx1 * sy - sx * dy1) / det if det != 0.0 else 0.0
    out = np.empty(8)
    out[0], out[1], out[2] = x1 - x0 + g * x1, x3 - x0 + h * x3, x0
    out[3], out[4], out[5] = y1 - y0 + g * y1, y3 - y0 + h * y3, y0
    out[6], out[7] = g, h
    return out


@jit
def fit_quads(
    gray: np.ndarray,
    quads: np.ndarray,
    cells: int,
    passes: int,
    samples: np.ndarray,
    steps: np.ndarray,
    reach: float,
    reach_low: float,
    reach_high: float,
) -> np.ndarray:
    """:func:`.edges.fit_edges` (which documents the method and the
    arguments) for quads (N, 4, 2) with its constants: points at ``samples`` (parts of an edge),
    each read at ``steps`` (parts of the reach) along the normal, the reach ``reach`` cells
    within ``reach_low`` and ``reach_high`` pixels."""
    out = quads.copy()
    s_count, l_count = len(samples), len(steps)
    offsets = np.empty(l_count)
    middles = np.empty(l_count - 1)
    levels = np.empty(l_count)
    points = np.empty((s_count, 2))
    strength = np.empty(s_count)
    centre = np.empty((4, 2))
    direction = np.empty((4, 2))
    crossing = np.empty((4, 2))
    for n in range(len(out)):
        q = out[n]
        side = 0.0
        for k in range(4):
            side += math.hypot(q[NEXT[k], 0] - q[k, 0], q[NEXT[k], 1] - q[k, 1])
        side /= 4
        r = min(max(reach * side / cells, reach_low), reach_high)
        for i in range(l_count):
            offsets[i] = steps[i] * r
        for i in range(l_count - 1):
            middles[i] = (offsets[i + 1] + offsets[i]) / 2
        limit = max(2.0, 0.25 * side)
        for _ in range(passes):
            mx = (q[0, 0] + q[1, 0] + q[2, 0] + q[3, 0]) / 4
            my = (q[0, 1] + q[1, 1] + q[2, 1] + q[3, 1]) / 4
            for k in range(4):
                ex, ey = q[NEXT[k], 0] - q[k, 0], q[NEXT[k], 1] - q[k, 1]
                length = math.hypot(ex, ey)
                nx, ny = ey / length, -ex / length
                outward = (q[k, 0] + ex / 2 - mx) * nx + (q[k, 1] + ey / 2 - my) * ny
                sign = 1.0 if outward > 0 else (-1.0 if outward < 0 else 0.0)
                nx, ny = nx * sign, ny * sign
                for s in range(s_count):
                    px, py = q[k, 0] + samples[s] * ex, q[k, 1] + samples[s] * ey
                    for i in range(l_count):
                        levels[i] = bilinear(gray, px + offsets[i] * nx, py + offsets[i] * ny)
                    total, moment = 0.0, 0.0
                    for i in range(l_count - 1):
                        rise = max(levels[i + 1] - levels[i], 0.0)
                        total += rise
                        moment += rise * middles[i]
                    shift = moment / max(total, 1e-6)
                    points[s, 0], points[s, 1] = px + shift * nx, py + shift * ny
                    strength[s] = total
                # Points where the edge hardly rises (a highlight, an occluder) do not pull it.
                middle = np.sort(strength)[s_count // 2]
                _line(points, strength > 0.3 * middle, centre[k], direction[k])
            for k in range(4):
                _cross(
                    centre[PREVIOUS[k]],
                    direction[PREVIOUS[k]],
                    centre[k],
                    direction[k],
                    crossing[k],
                )
            for k in range(4):
                moved = math.hypot(crossing[k, 0] - q[k, 0], crossing[k, 1] - q[k, 1])
                if np.isfinite(crossing[k, 0]) and np.isfinite(crossing[k, 1]) and moved <= limit:
                    q[k, 0], q[k, 1] = crossing[k, 0], crossing[k, 1]
    return out


@jit
def _line(
    points: np.ndarray, weight: np.ndarray, centre: np.ndarray, direction: np.ndarray
) -> None:
    """The weighted least-squares line through ``points`` (S, 2), into ``centre`` and the unit
    ``direction`` (the principal axis of the points' scatter)."""
    total, cx, cy = 0.0, 0.0, 0.0
    for s in range(len(points)):
        if weight[s]:
            total += 1.0
            cx += points[s, 0]
            cy += points[s, 1]
    total = max(total, 1e-9)
    cx, cy = cx / total, cy / total
    sxx, syy, sxy = 0.0, 0.0, 0.0
    for s in range(len(points)):
        if weight[s]:
            dx, dy = points[s, 0] - cx, points[s, 1] - cy
            sxx += dx * dx
            syy += dy * dy
            sxy += dx * dy
    angle = 0.5 * math.atan2(2 * sxy, sxx - syy)
    centre[0], centre[1] = cx, cy
    direction[0], direction[1] = math.cos(angle), math.sin(angle)


@jit
def _cross(c1: np.ndarray, d1: np.ndarray, c2: np.ndarray, d2: np.ndarray, out: np.ndarray) -> None:
    """Where the lines ``c1 + s d1`` and ``c2 + t d2`` cross, into ``out`` (NaN if parallel)."""
    det = d1[0] * d2[1] - d1[1] * d2[0]
    if det == 0.0:
        out[0] = out[1] = np.nan
        return
    s = ((c2[0] - c1[0]) * d2[1] - (c2[1] - c1[1]) * d2[0]) / det
    out[0], out[1] = c1[0] + s * d1[0], c1[1] + s * d1[1]


@jit
def repeats(quads: np.ndarray) -> np.ndarray:
    """Which quads (N, 4, 2) repeat an earlier one: their centres within a pixel and 5 % of
    its size, their sizes (the larger extent in x or y) within 10 % of its size."""
    n = len(quads)
    centres = np.zeros((n, 2))
    sides = np.zeros(n)
    for i in range(n):
        for a in range(2):
            lo, hi = quads[i, 0, a], quads[i, 0, a]
            for k in range(4):
                centres[i, a] += quads[i, k, a] / 4
                lo, hi = min(lo, quads[i, k, a]), max(hi, quads[i, k, a])
            sides[i] = max(sides[i], hi - lo)
    out = np.zeros(n, np.bool_)
    for i in range(n):
        for j in range(i):
            near = math.hypot(centres[i, 0] - centres[j, 0], centres[i, 1] - centres[j, 1])
            if near <= 1.0 + 0.05 * sides[j] and abs(sides[i] - sides[j]) <= 0.1 * sides[j]:
                out[i] = True
                break
    return out
