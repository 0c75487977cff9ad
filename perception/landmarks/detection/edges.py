"""Sub-pixel marker corners from straight lines fitted to the black square's four edges.

A corner found as a contour's vertex is good to a pixel; the square's edges are straight over
many pixels, so a line fitted to them is good to a small fraction of one, and two adjacent lines
cross at the corner. Each edge is sampled at a few points; at each, the grey levels along the
edge's normal (inside the black square to outside it) locate the edge where they rise, as the
centroid of that rise; a least-squares line through those points is the edge. The normal is
read no farther than most of one cell on either side, so the data cells inside the black border
and whatever lies beyond the white border stay out of it. All markers of an image are fitted in
one compiled call (:func:`.quads_kernels.fit_quads`), grey levels
sampled bilinearly in OpenCV's pixel convention (the centre of the top-left pixel at (0, 0)).
"""

from __future__ import annotations

import numpy as np

from percept.perception.landmarks.detection.quads_kernels import fit_quads

SAMPLES = np.linspace(0.15, 0.85, 8)  # along each edge, away from the corners' rounding
STEPS = np.linspace(-1.0, 1.0, 17)  # along the normal, in units of the reach
REACH = 0.8  # cells of the marker either side of the edge
REACH_PIXELS = (1.0, 4.0)  # the reach's bounds in pixels: blur needs 1, clutter stops at 4


def fit_edges(gray: np.ndarray, corners: np.ndarray, cells: int, passes: int = 2) -> np.ndarray:
    """Corners (N, 4, 2) of dark squares of ``cells`` cells a side moved onto the crossings of
    lines fitted to their edges in ``gray``, each of ``passes`` from the last one's corners (the
    second moves them by hundredths of a pixel); a corner that would move farther than a
    quarter of its square's side (or 2 px) keeps its place."""
    q = np.ascontiguousarray(corners, dtype=float)
    if len(q) == 0:
        return q
    return fit_quads(
        np.ascontiguousarray(gray), q, cells, passes, SAMPLES, STEPS, REACH, *REACH_PIXELS
    )
