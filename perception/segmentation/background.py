"""The background model of §4.1: per-pixel statistics of Y, Cr, Cb learned once, then frozen.

A pixel is foreground when ``|i_c(p) - mu_c(p)| > k * max(sigma_c(p), sigma_min)`` in any channel.
For 8-bit images that test is the same as ``i_c(p)`` lying outside the integer interval
``[ceil(mu - k s), floor(mu + k s)]``, so the bounds are computed once after calibration and each
frame is classified with one ``cv2.inRange`` call (about 20x faster than the float test).

Use it like an OpenCV ``BackgroundSubtractor`` whose learning stops after calibration::

    model = BackgroundModel.calibrate(frames, params)   # frames: BGR images or grid frames
    mask = model.apply(image)                           # 0/255, 255 = foreground
"""

from __future__ import annotations

import logging
import zipfile
from collections.abc import Callable, Iterable
from pathlib import Path

import cv2
import numpy as np

from percept.perception.colour import to_ycrcb
from percept.perception.params import BackgroundParams
from percept.perception.segmentation.grid_frame import PerceptionFrame, as_ycrcb

log = logging.getLogger("percept.perception.background")

Progress = Callable[[int, int], None]
"""Called as ``progress(done, total)`` while calibration collects frames."""

MAD_TO_SIGMA = 1.4826
"""Median absolute deviation of normal noise times this is its standard deviation."""

_ROWS_PER_CHUNK_PIXELS = 1 << 21
"""Samples per chunk of rows while computing statistics (bounds the float working memory)."""


class CalibrationError(Exception):
    """Calibration got no usable frames, or frames of different sizes."""


class BackgroundModel:
    """Per-pixel mean ``mu`` and deviation ``sigma`` of Y, Cr, Cb, and the foreground test."""

    def __init__(self, mean: np.ndarray, sigma: np.ndarray, params: BackgroundParams) -> None:
        if mean.shape != sigma.shape or mean.ndim != 3 or mean.shape[2] != 3:
            raise ValueError(f"mean {mean.shape} and sigma {sigma.shape} must both be (H, W, 3)")
        self.params = params
        self.mean = mean.astype(np.float32)
        self.sigma = sigma.astype(np.float32)
        self.lower, self.upper = self.bounds(params.k)

    def on_grid(self, step: int) -> BackgroundModel:
        """This model for the grid of every ``step``-th pixel of every ``step``-th row."""
        if step == 1:
            return self
        return BackgroundModel(self.mean[::step, ::step], self.sigma[::step, ::step], self.params)

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) of the images this model classifies."""
        return self.mean.shape[0], self.mean.shape[1]

    def scale(self, k: float) -> np.ndarray:
        """``k * max(sigma, sigma_min)`` per pixel and channel."""
        return k * np.maximum(self.sigma, self.params.sigma_min)

    def bounds(self, k: float) -> tuple[np.ndarray, np.ndarray]:
        """Integer ``[lower, upper]`` of background intensities for threshold ``k`` (uint8)."""
        s = self.scale(k)
        lower = np.clip(np.ceil(self.mean - s), 0, 255).astype(np.uint8)
        upper = np.clip(np.floor(self.mean + s), 0, 255).astype(np.uint8)
        return lower, upper

    def classify(self, ycc: np.ndarray) -> np.ndarray:
        """Foreground of a YCrCb image as a 0/1 uint8 mask (before noise reduction)."""
        background = cv2.inRange(ycc, self.lower, self.upper)
        return cv2.threshold(background, 0, 1, cv2.THRESH_BINARY_INV)[1]

    def apply(self, image: np.ndarray) -> np.ndarray:
        """Foreground of a BGR image as a 0/255 mask, like ``BackgroundSubtractor.apply``."""
        background = cv2.inRange(to_ycrcb(image), self.lower, self.upper)
        return cv2.bitwise_not(background)

    @classmethod
    def calibrate(
        cls,
        frames: Iterable[PerceptionFrame],
        params: BackgroundParams,
        progress: Progress | None = None,
    ) -> BackgroundModel:
        """Learn the background from the first ``params.calibration_frames`` frames: BGR images,
        or grid frames (the model is then of the grid).

        With the ``clipped`` estimator people or objects that pass by during calibration are
        left out, as long as each pixel shows the background in most frames.
        """
        total = params.calibration_frames
        # One array for all frames, filled in place: a list of frames and a stacked copy would
        # leave a long-running process with twice the stack's size of freed but resident heap.
        stack: np.ndarray | None = None
        n = 0
        for frame in frames:
            ycc = as_ycrcb(frame)
            if stack is None:
                problem = params.memory_problem(ycc.shape[1], ycc.shape[0])
                if problem is not None:  # checked on the real frame size, before allocating
                    raise CalibrationError(problem)
                stack = np.empty((total, *ycc.shape), np.uint8)
            elif ycc.shape != stack.shape[1:]:
                raise CalibrationError(
                    f"calibration frame {n + 1} is {ycc.shape}, the first was {stack.shape[1:]}"
                )
            stack[n] = ycc
            n += 1
            if progress is not None:
                progress(n, total)
            if n >= total:
                break
        if stack is None:
            raise CalibrationError("no calibration frames")
        if n < total:
            log.warning("calibrated on %d frames, fewer than the %d asked for", n, total)
        mean, sigma = pixel_statistics(stack[:n], params)
        return cls(mean, sigma, params)

    def save(self, path: str | Path) -> None:
        """Write ``mean`` and ``sigma`` to an ``.npz`` file (thresholds are applied at load)."""
        np.savez_compressed(path, mean=self.mean, sigma=self.sigma)

    @classmethod
    def load(cls, path: str | Path, params: BackgroundParams) -> BackgroundModel:
        """Read a calibration written by :meth:`save`; ``params`` give the thresholds.

        Raises :class:`CalibrationError` for anything else (a folder, random bytes, other arrays).
        """
        try:
            data = np.load(path)
        except (OSError, EOFError, ValueError, zipfile.BadZipFile) as err:
            # np.load reads foreign bytes as a pickle it refuses (ValueError) or fails (OSError).
            what = err.strerror if isinstance(err, OSError) and err.strerror else "not .npz"
            raise CalibrationError(
                f"{path}: not a background model saved by percept ({what})"
            ) from None
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise CalibrationError(f"{path}: one array, not a background model saved by percept")
        with data:
            try:
                return cls(data["mean"], data["sigma"], params)
            except (KeyError, ValueError, zipfile.BadZipFile, EOFError) as err:
                raise CalibrationError(
                    f"{path}: not a background model saved by percept ({err})"
                ) from None


def pixel_statistics(stack: np.ndarray, params: BackgroundParams) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel ``(mu, sigma)`` of a ``(frames, H, W, 3)`` uint8 stack, by ``params.estimator``.

    The work goes in chunks of rows so that a long calibration does not need the whole stack
    in floating point at once.
    """
    n, height, width, _ = stack.shape
    mean = np.empty((height, width, 3), np.float32)
    sigma = np.empty((height, width, 3), np.float32)
    rows = max(1, _ROWS_PER_CHUNK_PIXELS // max(1, n * width * 3))
    for top in range(0, height, rows):
        chunk = stack[:, top : top + rows].astype(np.float32)
        if params.estimator == "mean":
            m, s = chunk.mean(axis=0), chunk.std(axis=0)
        else:
            m, s = _clipped(chunk, params.clip)
        mean[top : top + rows], sigma[top : top + rows] = m, s
    return mean, sigma


def _clipped(samples: np.ndarray, clip: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean and deviation of the samples within ``clip`` robust sigmas of the median.

    The robust sigma is 1.4826 MAD, but at least one grey level: with 8-bit quantisation the
    MAD of a steady pixel is often 0, and a zero width would reject its ordinary noise too.
    """
    median = np.median(samples, axis=0)
    spread = np.abs(samples - median)
    robust = np.maximum(MAD_TO_SIGMA * np.median(spread, axis=0), 1.0)
    keep = spread <= clip * robust
    count = keep.sum(axis=0)  # >= 1: the sample at the median is always kept
    mean = np.where(keep, samples, 0.0).sum(axis=0) / count
    var = np.where(keep, (samples - mean) ** 2, 0.0).sum(axis=0) / count
    return mean, np.sqrt(var)


def describe(model: BackgroundModel) -> str:
    """One line for the log: size and typical deviation per channel."""
    h, w = model.shape
    typical = np.median(model.sigma.reshape(-1, 3), axis=0)
    return f"{w}x{h}, median sigma Y {typical[0]:.2f} Cr {typical[1]:.2f} Cb {typical[2]:.2f}"
