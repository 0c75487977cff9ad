"""The images of point sets through a pinhole camera: each set's bounding box in pixels and the
area of its convex hull, the measurements of the footprint fit
(:mod:`percept.perception.features.footprint`).

A Newton step of the fit measures some six point sets of a few dozen points; in numpy and
OpenCV that was a projection, two reductions and, per set, a convex hull and its area: about
40 Python-level calls and 120 µs a step. Here it is one loop. The projection is the same
expression as :meth:`percept.kinematics.camera.CameraModel.project`'s undistorted branch; the hull
is taken of the points rounded to float32, as OpenCV's ``convexHull`` takes them.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def hull_area(u: np.ndarray, v: np.ndarray) -> float:
    """Area of the convex hull of the points ``(u, v)`` (m,): Andrew's monotone chain, then the
    shoelace sum."""
    m = u.shape[0]
    by_v = np.argsort(v, kind="mergesort")
    order = by_v[np.argsort(u[by_v], kind="mergesort")]  # by u, ties by v
    hull = np.empty(2 * m, np.intp)
    k = 0
    for j in range(m):  # the lower chain, left to right
        i = order[j]
        while k >= 2 and _turn(u, v, hull[k - 2], hull[k - 1], i) <= 0:
            k -= 1
        hull[k] = i
        k += 1
    lower = k + 1
    for j in range(m - 2, -1, -1):  # the upper chain, back
        i = order[j]
        while k >= lower and _turn(u, v, hull[k - 2], hull[k - 1], i) <= 0:
            k -= 1
        hull[k] = i
        k += 1
    area = 0.0
    for j in range(k - 1):  # the last point is the first again
        a, b = hull[j], hull[j + 1]
        area += u[a] * v[b] - u[b] * v[a]
    return abs(area) / 2


@jit
def _turn(u: np.ndarray, v: np.ndarray, a: int, b: int, c: int) -> float:
    """Twice the signed area of the triangle a, b, c (positive: counter-clockwise in u, v)."""
    return (u[b] - u[a]) * (v[c] - v[a]) - (v[b] - v[a]) * (u[c] - u[a])


@jit
def outline_images(
    points: np.ndarray, R: np.ndarray, t: np.ndarray, K: np.ndarray, area: bool
) -> np.ndarray:
    """(left, right, top, bottom, area) in pixels (n, 5) of the images of point sets
    ``points`` (n, m, 3) in the ground frame, seen by the camera at pose ``R``, ``t`` (camera
    axes in the ground frame's columns, the chapter's camera frame: x forward) with intrinsics
    ``K``; the area only when ``area`` (else NaN). A row is NaN where a set is not wholly in front
    of the camera."""
    n, m = points.shape[0], points.shape[1]
    out = np.full((n, 5), np.nan)
    u, v = np.empty(m), np.empty(m)
    hu, hv = np.empty(m), np.empty(m)  # rounded to float32 for the hull, as OpenCV's
    for i in range(n):
        front = True
        for j in range(m):
            dx = points[i, j, 0] - t[0]
            dy = points[i, j, 1] - t[1]
            dz = points[i, j, 2] - t[2]
            x = dx * R[0, 0] + dy * R[1, 0] + dz * R[2, 0]
            if x <= 0:
                front = False
                break
            y = dx * R[0, 1] + dy * R[1, 1] + dz * R[2, 1]
            z = dx * R[0, 2] + dy * R[1, 2] + dz * R[2, 2]
            a, b = -y / x, -z / x
            u[j] = K[0, 0] * a + K[0, 1] * b + K[0, 2]
            v[j] = K[1, 1] * b + K[1, 2]
        if not front:
            continue
        out[i, 0], out[i, 1] = u.min(), u.max()
        out[i, 2], out[i, 3] = v.min(), v.max()
        if area:
            for j in range(m):
                hu[j], hv[j] = np.float32(u[j]), np.float32(v[j])
            out[i, 4] = hull_area(hu, hv)
    return out
