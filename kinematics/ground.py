"""Pixel rays onto the ground plane (z = 0 of the robot's ground frame), and heights.

SPEC §4.5: the ray ``v_c`` of a pixel, rotated into the ground frame, ``v_t = R_c v_c``, meets the
ground at ``t_c + a v_t`` with ``a = -t_c,z / v_t,z``, which exists only below the horizon
(``v_t,z < 0``). A ray at or above the horizon, or one that would meet the ground farther than
``max_distance`` (where a pixel's width spans metres and the position means nothing), has no
ground point: the result says so explicitly (``on_ground`` False / ``valid`` False); it is never
NaN or a huge number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from percept.kinematics.camera import cv_from_ground
from percept.kinematics.pose import CameraPose

#: Rays meeting the ground farther than this (metres, horizontally) count as at the horizon.
MAX_DISTANCE = 50.0


@dataclass(frozen=True)
class GroundPoint:
    """Where a ray meets the ground: ``x, y`` in metres in the ground frame when ``on_ground``;
    both None when the ray does not meet the ground (at or above the horizon)."""

    on_ground: bool
    x: float | None = None
    y: float | None = None

    def __post_init__(self) -> None:
        if self.on_ground != (self.x is not None and self.y is not None):
            raise ValueError("a GroundPoint has x and y exactly when it is on the ground")


def ground_points(
    pose: CameraPose, rays: np.ndarray, max_distance: float = MAX_DISTANCE
) -> tuple[np.ndarray, np.ndarray]:
    """Ground positions ``xy`` (N, 2) of camera-frame rays (N, 3), and ``valid`` (N,) bool.

    Rows that do not meet the ground (see module doc) are ``valid`` False and hold 0, 0.
    """
    rays = np.asarray(rays, dtype=float).reshape(-1, 3)
    v = rays @ pose.R.T
    tz = float(pose.t[2])
    valid = v[:, 2] < 0
    if tz <= 0:
        valid[:] = False
    # Only the rays down to the ground divide: no division by zero (asked per anchor per frame,
    # where silencing numpy's warnings cost as much as the arithmetic).
    a = -tz / np.where(valid, v[:, 2], -1.0)
    xy = pose.t[:2] + a[:, None] * v[:, :2]
    d = xy - pose.t[:2]
    valid &= np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) <= max_distance
    xy[~valid] = 0.0
    return xy, valid


def ground_point(pose: CameraPose, ray: np.ndarray, max_distance: float = MAX_DISTANCE):
    """The :class:`GroundPoint` of one camera-frame ray (3,)."""
    xy, valid = ground_points(pose, np.asarray(ray, dtype=float)[None, :], max_distance)
    if not valid[0]:
        return GroundPoint(on_ground=False)
    return GroundPoint(on_ground=True, x=float(xy[0, 0]), y=float(xy[0, 1]))


def height_at(pose: CameraPose, ray: np.ndarray, ground_xy: np.ndarray) -> float | None:
    """Height (z, metres) where the camera-frame ``ray`` meets the vertical plane through the
    object's ground position ``ground_xy`` that faces the camera (its normal is the horizontal
    direction from the camera to the object). None when the ray does not meet that plane in
    front of the camera, or the object stands right below the camera (no facing direction)."""
    v = pose.R @ np.asarray(ray, dtype=float).reshape(3)
    gx, gy = (float(c) for c in np.asarray(ground_xy, dtype=float).reshape(2))
    # In Python floats: two-element arrays cost more in numpy's calls than in their arithmetic.
    nx, ny = gx - float(pose.t[0]), gy - float(pose.t[1])
    reach = math.sqrt(nx * nx + ny * ny)
    if reach < 1e-9:
        return None
    nx, ny = nx / reach, ny / reach
    toward = nx * float(v[0]) + ny * float(v[1])
    if toward <= 1e-12:
        return None
    s = reach / toward
    return float(pose.t[2] + s * v[2])


def ground_homography(K: np.ndarray, pose: CameraPose) -> np.ndarray:
    """The 3x3 homography from ground-plane points ``(x, y, 1)`` (metres) to the pixels
    ``(u, v, 1)`` of an undistorted pinhole with camera matrix ``K`` at ``pose``."""
    T = cv_from_ground(pose)
    return K @ T[:3, [0, 1, 3]]


def view_homography(K: np.ndarray, before: CameraPose, after: CameraPose) -> np.ndarray:
    """The 3x3 homography taking a pixel of the view from ``before`` to the pixel of the same
    ground point in the view from ``after`` (lens distortion ignored).

    Exact for whatever lies on the ground; for a camera that only rotates it is the rotation's
    homography ``K R K^-1`` and exact for every pixel. Objects standing on the ground move with
    it up to a parallax of their height times the camera's translation over their distance.
    """
    H = ground_homography(K, after) @ np.linalg.inv(ground_homography(K, before))
    return H / H[2, 2]
