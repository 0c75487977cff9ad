"""Association scores (§4.4): each percept's model of highest ``s = s_space * s_color``."""

from __future__ import annotations

import math

import numpy as np

from percept.perception.compiled import jit


@jit
def best_models(
    boxes: np.ndarray,
    histograms: np.ndarray,
    centres: np.ndarray,
    models: np.ndarray,
    in_motion: np.ndarray,
    t_space: np.ndarray,
    t_color: np.ndarray,
    diagonal: float,
) -> np.ndarray:
    """Model index of each percept (highest non-zero score, the first of equals), or -1.

    Percept ``i`` has box ``boxes[i]`` (left, top, width, height) and histograms
    ``histograms[i]`` (factors, bins); model ``j`` has centre ``centres[j, :2]`` (the filter
    states, whole: a slice of them would be typed, and compiled, anew whenever it happens to be
    contiguous) and histograms ``models[j]``.
    ``s_space = 1 - distance / diagonal`` counts when above ``t_space``, ``s_color``, the
    product over the factors (Y, Cr, Cb) of the Bhattacharyya coefficients, when above
    ``t_color``; each threshold is a pair (still, in motion) picked by ``in_motion[j]``.
    """
    n, k = len(centres), len(boxes)
    root_percepts, root_models = np.sqrt(histograms), np.sqrt(models)
    best = np.full(k, -1, np.intp)
    for i in range(k):
        x = boxes[i, 0] + boxes[i, 2] / 2
        y = boxes[i, 1] + boxes[i, 3] / 2
        top = 0.0
        for j in range(n):
            moving = 1 if in_motion[j] else 0
            s_space = 1 - math.hypot(x - centres[j, 0], y - centres[j, 1]) / diagonal
            if not s_space > t_space[moving]:
                continue
            s_color = _bhattacharyya(root_percepts[i], root_models[j])
            if not s_color > t_color[moving]:
                continue
            score = s_space * s_color
            if score > top:
                best[i], top = j, score
    return best


@jit
def _bhattacharyya(root_a: np.ndarray, root_b: np.ndarray) -> float:
    """The product over the factors of the Bhattacharyya coefficients of two colour models
    ``(factors, bins)``, given as their square roots."""
    s_color = 1.0
    for c in range(root_a.shape[0]):
        coefficient = 0.0
        for b in range(root_a.shape[1]):
            coefficient += root_a[c, b] * root_b[c, b]
        s_color *= coefficient
    return s_color


@jit
def colour_similarity(percepts: np.ndarray, models: np.ndarray) -> np.ndarray:
    """``s_color`` of every percept (``(k, factors, bins)`` histograms) and model
    (``(n, factors, bins)``), as a ``(k, n)`` matrix."""
    root_percepts, root_models = np.sqrt(percepts), np.sqrt(models)
    out = np.empty((len(percepts), len(models)))
    for i in range(len(percepts)):
        for j in range(len(models)):
            out[i, j] = _bhattacharyya(root_percepts[i], root_models[j])
    return out
