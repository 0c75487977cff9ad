"""The per-pixel pass of :mod:`percept.perception.light.foreground`: a frame mapped to the
calibration's light, its foreground test and its shadow test, one row at a time.

The map is ``cv2.transform``'s with the photometry's matrix, to the bit: OpenCV finds the matrix
diagonal and maps each channel on its own, ``saturate_cast<uchar>(g * v + o)`` with the matrix's
entries rounded to float32 and the product and sum fused where OpenCV's code for the CPU fuses
them (:func:`percept.perception.compiled.fma`; ``fused``, which the caller finds out from OpenCV),
rounded half to even, a value at or beyond
the range of an int (or not a number) taken as 0. The foreground test is ``cv2.inRange`` on the
model's bounds, inverted; the shadow test is made where a row's test found foreground, while the
row is in the cache.

The map and the test run over a row's bytes, channels interleaved, which LLVM compiles to vector
instructions; the pixel's test is then the OR of its three bytes. Written over pixels, three
channels each, the same test took fifteen times as long: the compiler gathered the channels
lane by lane.
"""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import fma, jit

INT_RANGE = np.float32(2.0**31)
"""OpenCV rounds a float to an int with the CPU's conversion, which gives the smallest int for
anything at or beyond this (or not a number); saturated to uint8 that is 0."""


@jit
def light_foreground(
    ycc: np.ndarray,
    matrix: np.ndarray,
    compensated: bool,
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
) -> None:
    """Fill ``out`` (uint8 (H, W, 3)) with ``ycc`` (uint8 YCrCb (H, W, 3)) mapped by
    ``matrix`` (float32 (3, 4), diagonal: the photometry's) when ``compensated`` (else ``out``
    is not written and the test reads ``ycc``; ``fused``: the product and sum rounded once), and
    ``raw`` (uint8 (H, W)) with its 0/1
    foreground: 1 where a channel lies outside ``[lower, upper]`` (uint8 (H, W, 3)), but for
    shadow on ``mean`` and ``sigma`` (float32 (H, W, 3)) when ``shadows`` (:func:`_shadow`).
    All arrays C-contiguous."""
    height, width = raw.shape
    row = 3 * width
    source = ycc.reshape(-1)
    frame = out.reshape(-1) if compensated else source
    low, high = lower.reshape(-1), upper.reshape(-1)
    mask = raw.reshape(-1)
    centre, spread = mean.reshape(-1), sigma.reshape(-1)
    gain = np.empty(row, np.float32)  # the matrix's entries for each byte of a row
    offset = np.empty(row, np.float32)
    for k in range(row):
        gain[k], offset[k] = matrix[k % 3, k % 3], matrix[k % 3, 3]
    outside = np.empty(row, np.uint8)  # a row's test, per byte
    for v in range(height):
        start = v * row
        if compensated:
            for k in range(row):
                level = _mapped(gain[k], offset[k], source[start + k], fused)
                frame[start + k] = level
                outside[k] = (level < low[start + k]) | (level > high[start + k])
        else:
            for k in range(row):
                level = source[start + k]
                outside[k] = (level < low[start + k]) | (level > high[start + k])
        first = v * width
        found = False
        for u in range(width):
            fg = outside[3 * u] | outside[3 * u + 1] | outside[3 * u + 2]
            mask[first + u] = fg
            found |= fg != 0
        if not (found and shadows):
            continue
        for u in range(width):
            if mask[first + u] and _shadow(
                frame, centre, spread, start + 3 * u, sigma_min, darkest, chroma
            ):
                mask[first + u] = 0


@jit
def _mapped(gain: np.float32, offset: np.float32, value: np.uint8, fused: bool) -> np.uint8:
    """``saturate_cast<uchar>(gain * value + offset)`` as OpenCV computes it (the product and sum
    rounded once when ``fused``). Clipped to 0..255 before rounding, which gives the same (both
    bounds are integers, rounding is monotonic)."""
    level = fma(gain, np.float32(value), offset) if fused else gain * np.float32(value) + offset
    if not level < INT_RANGE:
        return np.uint8(0)
    level = min(max(level, np.float32(0.0)), np.float32(255.0))
    return np.uint8(np.rint(level))


@jit
def _shadow(
    frame: np.ndarray,
    mean: np.ndarray,
    sigma: np.ndarray,
    k: int,
    sigma_min: float,
    darkest: float,
    chroma: float,
) -> bool:
    """Whether the pixel whose Y is byte ``k`` of ``frame`` (flat YCrCb) is shadow on a
    background of ``mean`` and ``sigma`` (flat alike): Y at a fraction ``r`` of the mean's with
    ``darkest <= r < 1``, Cr and Cb within ``chroma * max(sigma, sigma_min)`` of ``128 + r
    (mean - 128)``, and a grey surface (Cr = Cb = 128) farther than that from it in Cr or Cb."""
    ratio = np.float32(frame[k]) / max(mean[k], np.float32(1.0))
    if ratio < darkest or ratio >= 1.0:
        return False
    shadow, telling = True, False
    for c in range(1, 3):
        bound = chroma * max(sigma[k + c], sigma_min)
        expected = 128.0 + ratio * (mean[k + c] - 128.0)
        if abs(frame[k + c] - expected) > bound:
            shadow = False
        if abs(expected - 128.0) > bound:
            telling = True
    return shadow and telling
