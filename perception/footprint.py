"""An upright cylinder on the ground whose image has a given bounding box.

A bounding box has four numbers (its left, right, top and bottom edge); an upright cylinder
standing on the ground has four unknowns (the centre x, y of its footprint, its diameter and its
height). So, with the camera's pose known, one cylinder fits, and Newton's method finds it from a
nearby start. Unlike the chapter's construction this accounts for the perspective of a camera that
looks down (the top sticks out sideways and its far rim is the bounding box's top edge) and for the
lean of vertical edges away from the image centre. A round footprint is the middle ground between
the shapes on a table: boxes (wider at the top in the image), cones, balls and toys (narrower).
"""

from __future__ import annotations

import numpy as np

from kinematics.camera import CameraModel
from kinematics.pose import CameraPose

_RING = 16  # points per rim: the outline is then within 2 % of the circle's
_ANGLES = np.linspace(0.0, 2.0 * np.pi, _RING, endpoint=False)
# Unit cylinder: diameter 1, height 1, footprint centred on the origin.
_UNIT = np.vstack(
    [
        np.column_stack([0.5 * np.cos(_ANGLES), 0.5 * np.sin(_ANGLES), np.full(_RING, z)])
        for z in (0, 1)
    ]
)
_STEP = 1e-5  # metres, for the numeric Jacobian
_TOLERANCE = 1e-3  # pixels


def _edges(camera: CameraModel, pose: CameraPose, params: np.ndarray) -> np.ndarray:
    """(left, right, top, bottom) image edges (len(params), 4) of cylinders ``(x, y, diameter,
    height)``; NaN where part of one is not in front of the camera."""
    offset = np.zeros((len(params), 3))
    offset[:, :2] = params[:, :2]
    points = _UNIT * params[:, None, [2, 2, 3]] + offset[:, None, :]
    uv = camera.project((points.reshape(-1, 3) - pose.t) @ pose.R).reshape(len(params), -1, 2)
    low, high = uv.min(axis=1), uv.max(axis=1)
    return np.column_stack([low[:, 0], high[:, 0], low[:, 1], high[:, 1]])


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
    target = np.asarray(edges, dtype=float)
    p = np.asarray(start, dtype=float)
    variants = np.vstack([np.zeros(4), np.eye(4) * _STEP])
    for _ in range(iterations):
        projected = _edges(camera, pose, p + variants)
        if not np.isfinite(projected).all():
            return None
        residual = projected[0] - target
        if np.abs(residual).max() < _TOLERANCE:
            return (float(p[0]), float(p[1]), float(p[2]), float(p[3]))
        jacobian = (projected[1:] - projected[0]).T / _STEP
        try:
            p = p - np.linalg.solve(jacobian, residual)
        except np.linalg.LinAlgError:
            return None
        if p[2] <= 0 or p[3] <= 0:
            return None
    return None
