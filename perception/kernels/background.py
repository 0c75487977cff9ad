"""The background model's integer bounds, per pixel of the still model and per cell of the moving
head's map: the one arithmetic of the foreground test's bounds ``mean -+ k * max(sigma,
sigma_min)`` (rounded inwards) and the motion test's ``k_m * max(sigma, sigma_min)`` (rounded
down), in float32, clipped to 0-255."""

from __future__ import annotations

import numpy as np

from percept.perception.kernels import jit


@jit
def byte(value: float) -> int:
    """``value`` clipped to 0-255, as an integer (it is whole already)."""
    return int(min(max(value, 0.0), 255.0))


@jit
def test_bounds(
    mean: np.float32, sigma: np.float32, k: np.float32, sigma_min: np.float32
) -> tuple[int, int]:
    """The lowest and highest background value of one channel (float32 arguments)."""
    scaled = k * max(sigma, sigma_min)
    return byte(np.ceil(mean - scaled)), byte(np.floor(mean + scaled))


@jit
def noise_bound(sigma: np.float32, k: np.float32, sigma_min: np.float32) -> int:
    """The largest change of one channel that is noise (float32 arguments)."""
    return byte(np.floor(k * max(sigma, sigma_min)))


@jit
def model_bounds(
    mean: np.ndarray,
    sigma: np.ndarray,
    k: float,
    motion_k: float,
    sigma_min: float,
    lower: np.ndarray,
    upper: np.ndarray,
    moved: np.ndarray,
) -> None:
    """:func:`test_bounds` with ``k`` into ``lower`` and ``upper`` and :func:`noise_bound` with
    ``motion_k`` into ``moved`` (uint8) of every value of ``mean`` and ``sigma`` (float32, all
    C-contiguous, of one shape)."""
    m, s = mean.ravel(), sigma.ravel()
    low, high, bound = lower.ravel(), upper.ravel(), moved.ravel()
    kf, mk, floor = np.float32(k), np.float32(motion_k), np.float32(sigma_min)
    for i in range(len(m)):
        low[i], high[i] = test_bounds(m[i], s[i], kf, floor)
        bound[i] = noise_bound(s[i], mk, floor)
