"""The per-frame steps of :class:`percept.perception.light.adaptation.LightAdaptation`, each
concern's kernels composed in the order of the data flow, so that a frame is two compiled calls
with OpenCV's opening between them (:func:`light_frame` before it, :func:`light_after` after).
A moving head's frame takes the samples of its photometry with :func:`view_samples`.

Called one by one from Python, the same kernels cost about as much again in the calls, the
arrays made for them and the numpy between them as in their work, at 176x144.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit
from percept.perception.light.foreground_kernels import light_foreground
from percept.perception.light.ghosts_kernels import ghost_regions
from percept.perception.light.masks_kernels import box_mask, mark_frame, paint_boxes, share_outside
from percept.perception.light.photometry.photometric_kernels import affine_map, fit_photometry


@jit
def light_frame(
    ycc: np.ndarray,
    boxes: np.ndarray,
    step: int,
    anchored: np.ndarray,
    compensation: bool,
    expected: np.ndarray,
    previous: np.ndarray,
    sample: int,
    current: np.ndarray,
    current_inliers: int,
    min_share: float,
    min_inliers: float,
    centre: np.ndarray,
    min_spread: float,
    hold: float,
    fused: bool,
    lower: np.ndarray,
    upper: np.ndarray,
    mean: np.ndarray,
    sigma: np.ndarray,
    sigma_min: float,
    shadows: bool,
    darkest: float,
    chroma: float,
    out: np.ndarray,
    raw: np.ndarray,
) -> tuple[np.ndarray, int, bool, float]:
    """A frame ``ycc`` (uint8 YCrCb on the grid of ``step``) up to its foreground: the anchors'
    ``boxes`` painted into ``anchored`` (:func:`.masks_kernels.paint_boxes`); when
    ``compensation``, the photometry fitted on the samples of every ``sample``-th pixel outside
    them and the last frame's foreground ``previous``, from ``current`` (the photometry in use,
    on ``current_inliers``; :func:`.photometry.photometric_kernels.fit_photometry` and its
    arguments);
    the frame mapped by it into ``out`` and its 0/1 foreground into ``raw``, shadows dropped
    when ``shadows`` (:func:`.foreground_kernels.light_foreground` and its arguments).

    Returns the photometry in use after the fit with its inliers (as ``fit_photometry``: -1
    ``current`` kept, 0 the identity), whether ``out`` holds the frame (else it is ``ycc``
    itself), and the share of the foreground outside the anchors on the sample grid
    (:func:`.masks_kernels.share_outside`)."""
    paint_boxes(boxes, step, anchored)
    photometry, inliers = current, -1
    if compensation:
        photometry, inliers = fit_photometry(
            ycc,
            expected,
            anchored,
            previous,
            sample,
            current,
            min_share,
            min_inliers,
            centre,
            min_spread,
            hold,
        )
    compensated = inliers > 0 or (inliers < 0 and current_inliers != 0)
    light_foreground(
        ycc,
        affine_map(photometry[0], photometry[1], centre).astype(np.float32),
        compensated,
        fused,
        lower,
        upper,
        mean,
        sigma,
        sigma_min,
        shadows,
        darkest,
        chroma,
        out,
        raw,
    )
    return photometry, inliers, compensated, share_outside(raw, anchored, sample)


@jit
def light_after(
    fg: np.ndarray,
    raw: np.ndarray,
    anchored: np.ndarray,
    holding: bool,
    ghosts: bool,
    t: float,
    tested_at: float,
    every: float,
    min_seed: int,
    ycc: np.ndarray,
    mean: np.ndarray,
    background_at: np.ndarray,
    settled_before: float,
    previous: np.ndarray,
    moving: np.ndarray,
    match: float,
    ring: int,
    busy: np.ndarray,
) -> tuple[float, np.ndarray, int]:
    """A frame's foreground after the opening, ``fg`` (0/1 uint8 (H, W); ``raw`` before it):
    while ``holding``, ``fg`` cleared outside the ``anchored`` pixels; else, with ``ghosts``
    and a test due (:func:`ghost_test_due`, last at ``tested_at``), its ghosts
    (:func:`.ghosts_kernels.ghost_regions` and its arguments; ``settled``: pixels last
    background at ``settled_before`` or earlier) cleared from ``fg`` and ``raw``; then
    ``raw`` marked at ``t`` into ``background_at`` and ``busy``
    (:func:`.masks_kernels.mark_frame`).

    Returns the time of the last ghost test, the ghosts (bool (H, W); (0, 0) when not tested)
    and how many regions they are."""
    height, width = fg.shape
    found = 0
    mask = np.zeros((0, 0), np.bool_)
    if holding:  # ``raw`` stays whole: the maintenance must keep off it
        for v in range(height):
            for u in range(width):
                if not anchored[v, u]:
                    fg[v, u] = 0
    elif ghosts and ghost_test_due(fg, anchored, min_seed, t, tested_at, every):
        tested_at = t
        settled = np.empty((height, width), np.bool_)
        for v in range(height):
            for u in range(width):
                settled[v, u] = background_at[v, u] <= settled_before
        mask, found = ghost_regions(
            fg, ycc, mean, anchored, settled, previous, moving, min_seed, match, ring
        )
        if found:
            for v in range(height):
                for u in range(width):
                    if mask[v, u]:
                        fg[v, u] = 0
                        raw[v, u] = 0
    mark_frame(raw, background_at, busy, t)
    return tested_at, mask, found


@jit
def ghost_test_due(
    fg: np.ndarray, anchored: np.ndarray, min_seed: int, t: float, tested_at: float, every: float
) -> bool:
    """Whether to look for ghosts in ``fg`` (0/1 uint8 (H, W)): at once when ``min_seed``
    pixels of it or more lie outside the ``anchored`` ones (bool (H, W)), else (a ghost under
    an anchor lasts) when some lie inside and the last test, at ``tested_at``, was ``every``
    seconds or more before ``t``; testing every frame's regions doubled the light's time."""
    height, width = fg.shape
    inside = outside = 0
    for v in range(height):
        for u in range(width):
            if fg[v, u]:
                if anchored[v, u]:
                    inside += 1
                else:
                    outside += 1
    return outside >= min_seed or (inside > 0 and t - tested_at >= every)


@jit
def view_samples(
    ycc: np.ndarray,
    boxes: np.ndarray,
    step: int,
    known: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    sample: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the photometry of a moving head's frame ``ycc`` (uint8 (H, W, 3), on the grid of
    ``step``) is fitted on, on the sparse grid of every ``sample``-th pixel of every
    ``sample``-th row: the frame there (contiguous), the middle of its view's bounds
    (``(lower + upper) // 2`` as float32: what the frame is expected to be) and the pixels left
    out (the view's unknown ones, not ``known``, and those inside the anchors' ``boxes``).
    One pass over those few pixels, where numpy made a mask of the whole grid and six copies."""
    height, width = known.shape
    boxed = box_mask(boxes, height, width, step)
    rows, cols = (height + sample - 1) // sample, (width + sample - 1) // sample
    frame = np.empty((rows, cols, 3), np.uint8)
    middle = np.empty((rows, cols, 3), np.float32)
    excluded = np.empty((rows, cols), np.bool_)
    for i in range(rows):
        v = i * sample
        for j in range(cols):
            u = j * sample
            excluded[i, j] = not known[v, u] or boxed[v, u]
            for c in range(3):
                frame[i, j, c] = ycc[v, u, c]
                middle[i, j, c] = (np.int32(lower[v, u, c]) + np.int32(upper[v, u, c])) // 2
    return frame, middle, excluded
