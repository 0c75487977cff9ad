"""The anchors' update of a frame (:meth:`percept.perception.tracking.anchors.AnchorTracker.update`)
in one compiled call, which composes the kernels of each concern in the order of the data flow:
the models' predicted boxes (:mod:`.kalman_kernels`), the motion in them (:mod:`.motion_kernels`),
the association (:mod:`.association_kernels`), the correction (:mod:`.anchors_kernels`), and the
tests that say whether anything is left for Python to do: a percept of no model (a seed of a new
one), a model unseen for too long (deleted or remembered), two models that may be doubles.

In the usual frame nothing is, and the frame's update is this call and the anchors' records. At
176x144 with 8 objects the same steps were six compiled calls and some 30 numpy calls on arrays
of eight, which cost several times their arithmetic. Each kernel keeps its own module, tests and
arithmetic: the results are those of the calls one by one, to the bit.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.tracking.anchors_kernels import correct, may_double
from percept.perception.tracking.association_kernels import best_models
from percept.perception.tracking.kalman_kernels import boxes as filter_boxes
from percept.perception.tracking.motion_kernels import MOST, moved_in_boxes


@jit
def track(
    current: np.ndarray,
    previous: np.ndarray,
    upper: np.ndarray,
    size: int,
    step: int,
    count: bool,
    in_motion: np.ndarray,
    boxes: np.ndarray,
    histograms: np.ndarray,
    counts: np.ndarray,
    regions: np.ndarray,
    x: np.ndarray,
    cov: np.ndarray,
    r: float,
    models: np.ndarray,
    t_space: np.ndarray,
    t_color: np.ndarray,
    diagonal: float,
    alpha: float,
    last_seen: np.ndarray,
    pixels: np.ndarray,
    t: float,
    width: int,
    height: int,
    turning: bool,
    max_absence: float,
    double: float,
) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """Motion, association and correction of the models (filter states ``x``, ``cov``, noise
    ``r``; histograms ``models``; ``last_seen``, ``pixels``) with the percepts (``boxes``,
    ``histograms``, ``counts``, ``regions``) of a frame at ``t``:
    ``(answered, in_motion, best, histograms, cut, steady)``.

    ``count``: the motion in the models' predicted boxes is counted here between the frames
    ``current`` and ``previous`` (grids of every ``step``-th pixel; still bounds ``upper``, close
    with a ``size`` square) of one view, as :meth:`~percept.perception.tracking.motion.Motion.
    fraction` counts it; else ``in_motion`` (n,) is the caller's. When the boxes read more than
    :data:`MOST` of the image (OpenCV's whole mask costs less) nothing is done and ``answered``
    is False: the caller counts the motion and calls again without ``count``.

    ``best``, ``histograms``, ``cut``: as :func:`best_models` and :func:`correct` give them
    (``x``, ``cov``, ``last_seen``, ``pixels`` corrected in place). ``steady``: every percept is
    a model's, every model was seen within ``max_absence``, and no two models seen at ``t`` and
    still may be doubles (:func:`may_double` with ``double``): the frame's update is done.
    """
    n = x.shape[0]
    moving = in_motion
    if count:
        grid = filter_boxes(x)
        if step > 1:
            grid = grid / step
        moved = moved_in_boxes(current, previous, upper, grid, size, MOST)
        if moved.shape[0] != n:
            return False, moving, np.full(boxes.shape[0], -1, np.intp), models.copy(), moving, False
        moving = moved > 0
    best = best_models(boxes, histograms, x, models, moving, t_space, t_color, diagonal)
    out, cut = correct(
        best,
        boxes,
        histograms,
        counts,
        regions,
        x,
        cov,
        r,
        models,
        alpha,
        last_seen,
        pixels,
        t,
        width,
        height,
        turning,
    )
    for i in range(best.shape[0]):
        if best[i] < 0:
            return True, moving, best, out, cut, False
    seen = np.empty(n, np.intp)
    k = 0
    for i in range(n):
        if not t - last_seen[i] <= max_absence:
            return True, moving, best, out, cut, False
        if last_seen[i] == t and not moving[i]:
            seen[k] = i
            k += 1
    steady = k < 2 or not may_double(filter_boxes(x), seen[:k], double)
    return True, moving, best, out, cut, steady
