"""What a real camera adds to the rendered image: its exposure, sensor noise and flicker.

Both are a pure function of (scene seed, camera, scene time), like everything else in the
simulated world. Drawing fresh Gaussian noise for every pixel of every frame would cost more
than rendering, so noise comes from a bank of pre-drawn fields: each frame takes one field at a
random offset (8 fields x 33 x 33 offsets), which no per-pixel statistic can tell from fresh
noise over the few hundred frames a background model looks at.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from percept.drivers.sim.scene import CameraEffects

_FIELDS = 8
_SHIFT = 32  # largest offset of a field, pixels


class Effects:
    """Noise and flicker for images of ``shape`` (height, width, 3) from camera ``stream``."""

    def __init__(self, settings: CameraEffects, seed: int, stream: int, shape: tuple[int, ...]):
        self.settings = settings
        self.seed = seed
        self.stream = stream
        self._bank: np.ndarray | None = None
        if settings.noise:
            h, w, c = shape
            rng = np.random.default_rng([seed, stream])
            noise = rng.standard_normal((_FIELDS, h + _SHIFT, w + _SHIFT, c), dtype=np.float32)
            self._bank = np.round(noise * settings.noise).astype(np.int16)

    @property
    def active(self) -> bool:
        return bool(self.settings.noise or self.settings.flicker)

    def apply(self, image: np.ndarray, t: float, exposure: float = 1.0) -> np.ndarray:
        """``image`` (BGR ``uint8``) as the camera delivers it at scene time ``t`` with
        ``exposure`` times its first exposure (the scene's ``exposure`` events)."""
        fx = self.settings
        if not self.active:
            return cv2.convertScaleAbs(image, alpha=exposure) if exposure != 1.0 else image
        rng = np.random.default_rng([self.seed, self.stream, round(t * 1e6)])
        gain = exposure
        if fx.flicker_hz > 0:
            gain += fx.flicker * math.sin(2 * math.pi * fx.flicker_hz * t)
        elif fx.flicker:
            gain += fx.flicker * rng.uniform(-1.0, 1.0)
        out = cv2.convertScaleAbs(image, alpha=gain) if gain != 1.0 else image
        if self._bank is not None:
            k, dy, dx = rng.integers(0, (_FIELDS, _SHIFT + 1, _SHIFT + 1))
            h, w = image.shape[:2]
            noise = self._bank[k, dy : dy + h, dx : dx + w]
            out = cv2.add(out, noise, dtype=cv2.CV_8U)
        return out
