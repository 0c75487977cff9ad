"""The anchors' correction after the association
(:meth:`percept.perception.tracking.anchors.AnchorTracker.update`) in one compiled call: the
percepts of each model combined, its filter corrected, its histograms blended, its time last seen,
pixel count and border flag set.

At 176x144 with 8 objects the same steps as numpy expressions were some 25 calls of 1-3 µs each,
more than the arithmetic. The arithmetic is that of the expressions, operation for operation
(a sum over a histogram's bins in numpy's pairwise order, :func:`_bin_sum`), so every value comes
out as before, which the tests check.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.compiled.boxes_kernels import on_border
from percept.perception.segmentation.percepts_kernels import merge_groups
from percept.perception.tracking.kalman_kernels import update
from percept.perception.tracking.permanence.memory_kernels import share


@jit
def correct(
    best: np.ndarray,
    boxes: np.ndarray,
    histograms: np.ndarray,
    counts: np.ndarray,
    regions: np.ndarray,
    x: np.ndarray,
    cov: np.ndarray,
    r: float,
    models: np.ndarray,
    alpha: float,
    last_seen: np.ndarray,
    pixels: np.ndarray,
    t: float,
    width: int,
    height: int,
    turning: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Correct the models that got percepts: ``(histograms, cut)`` after it.

    Percept ``i`` (``boxes``, ``histograms``, ``counts``, ``regions`` of the percept set) is
    model ``best[i]``'s, or no model's (-1). When a model got several, all percepts are combined
    per model (:func:`merge_groups`), else each is its model's as it is. Each such model's filter
    (rows of ``x`` and ``cov``, noise ``r``, in place) takes the percepts' box as measurement;
    its histograms (a copy of ``models`` is returned, the records handed out keep the old one)
    are blended with the percepts' (:func:`blend`); ``last_seen`` becomes ``t`` and ``pixels``
    the percepts' count (in place). ``cut``: the percepts' box reaches the border of the
    ``width`` x ``height`` image; while the head is ``turning``, such a model's rates are zeroed.
    """
    n = x.shape[0]
    out = models.copy()
    cut = np.zeros(n, np.bool_)
    per_model = np.zeros(n, np.intp)
    hits = 0
    for i in range(best.shape[0]):
        if best[i] >= 0:
            per_model[best[i]] += 1
            hits += 1
    if hits == 0:
        return out, cut
    taken = np.empty(hits, np.intp)
    k = 0
    for i in range(best.shape[0]):
        if best[i] >= 0:
            taken[k] = i
            k += 1
    if hits > 1 and per_model.max() > 1:
        rows = np.flatnonzero(per_model)
        group_of = np.full(n, -1, np.intp)
        for g in range(rows.shape[0]):
            group_of[rows[g]] = g
        groups = np.empty(hits, np.intp)
        for k in range(hits):
            groups[k] = group_of[best[taken[k]]]
        seen_boxes, seen, seen_counts, _ = merge_groups(
            groups, rows.shape[0], boxes[taken], histograms[taken], counts[taken], regions[taken]
        )
    else:
        rows = best[taken]
        seen_boxes, seen, seen_counts = boxes[taken], histograms[taken], counts[taken]
    z = np.empty((rows.shape[0], 4))
    for k in range(rows.shape[0]):
        left, top, w, h = seen_boxes[k, 0], seen_boxes[k, 1], seen_boxes[k, 2], seen_boxes[k, 3]
        z[k, 0], z[k, 1], z[k, 2], z[k, 3] = left + w / 2, top + h / 2, w, h
        cut[rows[k]] = on_border(left, top, w, h, width, height)
    update(x, cov, rows, z, r)
    blended = blend(models[rows], seen, alpha)
    for k in range(rows.shape[0]):
        j = rows[k]
        if turning and cut[j]:
            # A box cut by the border moves with the view's edge, not with its object.
            x[j, 4:] = 0.0
        out[j] = blended[k]
        last_seen[j] = t
        pixels[j] = seen_counts[k]
    return out, cut


@jit
def may_double(boxes: np.ndarray, rows: np.ndarray, double: float) -> bool:
    """Whether two of the ``boxes`` (n, 4) picked by ``rows`` (indices) lie one at least
    ``double`` inside the other (:func:`share`): the test of the anchors' doubles that compares
    no colours, made first because it rarely passes. When it does not, no two of them are
    doubles; when it does, the colours decide (in numpy, as the hues need its arithmetic)."""
    for a in range(rows.shape[0]):
        for b in range(a + 1, rows.shape[0]):
            i, j = rows[a], rows[b]
            if share(boxes[i], boxes[j]) >= double or share(boxes[j], boxes[i]) >= double:
                return True
    return False


@jit
def blend(models: np.ndarray, seen: np.ndarray, alpha: float) -> np.ndarray:
    """Models' histograms (k, factors, bins) updated with those ``seen`` (the same shape) of
    their objects (§4.4: ``M = (1 - alpha) M + alpha M_P``), normalised: the rule of every
    histogram update of the anchors."""
    out = np.empty_like(models)
    keep = 1 - alpha
    blended = np.empty(models.shape[2])
    for k in range(models.shape[0]):
        for c in range(models.shape[1]):
            for b in range(models.shape[2]):
                blended[b] = keep * models[k, c, b] + alpha * seen[k, c, b]
            total = _bin_sum(blended)
            for b in range(models.shape[2]):
                out[k, c, b] = blended[b] / total
    return out


@jit
def _bin_sum(a: np.ndarray) -> float:
    """``a.sum()`` of a contiguous 1-d array as numpy adds it up (pairwise: eight running sums
    over blocks of eight, added as a tree, then the rest), for the same rounding."""
    n = a.shape[0]
    if n < 8:
        total = a[0]
        for i in range(1, n):
            total += a[i]
        return total
    r = a[:8].copy()
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[i + j]
        i += 8
    total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        total += a[i]
        i += 1
    return total
