"""The points of upright solids on the ground whose images the footprint fit measures
(:mod:`percept.perception.features.footprint`).

Every Newton step of a fit measures the solid at its parameters and at each parameter moved a
little (the numeric Jacobian), so a frame asks for these outlines some fifteen times per object.
As numpy expressions one set cost 26 µs (frusta) and 110 µs (balls) in array calls on a few
dozen points; as loops, 2-3 µs. The arithmetic is numpy's, operation by operation (no fast-math),
so the points are the same to the bit.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def frusta(params: np.ndarray, rim: np.ndarray) -> np.ndarray:
    """Rim points (n, 2 m, 3) of frusta ``params`` (n, 5) ``(x, y, diameter, height, k)``: the
    footprint ``rim`` (m, 2, unit diameter) scaled by the diameter on the ground, then the top
    rim k times as wide at the height."""
    n, m = params.shape[0], rim.shape[0]
    out = np.empty((n, 2 * m, 3))
    for i in range(n):
        x, y, d, h, k = params[i, 0], params[i, 1], params[i, 2], params[i, 3], params[i, 4]
        top = k * d
        for j in range(m):
            out[i, j, 0] = x + d * rim[j, 0]
            out[i, j, 1] = y + d * rim[j, 1]
            out[i, j, 2] = 0.0
            out[i, m + j, 0] = x + top * rim[j, 0]
            out[i, m + j, 1] = y + top * rim[j, 1]
            out[i, m + j, 2] = h
    return out


@jit
def balls(params: np.ndarray, cx: float, cy: float, cz: float, rim: np.ndarray) -> np.ndarray:
    """Outline points (n, m, 3) of balls ``params`` (n, 3) ``(x, y, diameter)`` lying on the
    ground, as seen from a camera at ``(cx, cy, cz)``: the circle where the cone of sight touches
    the sphere, drawn with the points of ``rim`` (m, 2, unit diameter). NaN where the camera is
    inside a ball."""
    n, m = params.shape[0], rim.shape[0]
    out = np.empty((n, m, 3))
    for i in range(n):
        r = params[i, 2] / 2
        centre = (params[i, 0], params[i, 1], r)
        sx, sy, sz = centre[0] - cx, centre[1] - cy, centre[2] - cz
        reach = np.sqrt(sx * sx + sy * sy + sz * sz)
        ux, uy, uz = sx / reach, sy / reach, sz / reach
        # Across the line of sight: a horizontal unit vector (any one when the ball is straight
        # below the camera) and the third one of the right-handed frame.
        level = np.hypot(ux, uy)
        if level < 1e-9:
            ax, ay, az = 0.0, 1.0, 0.0
        else:
            ax, ay, az = -uy / level, ux / level, 0.0
        bx, by, bz = uy * az - uz * ay, uz * ax - ux * az, ux * ay - uy * ax
        diameter = 2 * r * np.sqrt(reach**2 - r**2) / reach  # of the circle of contact
        toward = r**2 / reach
        middle = (centre[0] - toward * ux, centre[1] - toward * uy, centre[2] - toward * uz)
        for j in range(m):
            s, c = rim[j, 0], rim[j, 1]
            out[i, j, 0] = middle[0] + diameter * (s * ax + c * bx)
            out[i, j, 1] = middle[1] + diameter * (s * ay + c * by)
            out[i, j, 2] = middle[2] + diameter * (s * az + c * bz)
    return out
