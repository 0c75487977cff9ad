"""What a real camera adds to the rendered image: its exposure and white balance, motion blur,
sensor noise, flicker and JPEG compression.

Both are a pure function of (scene seed, camera, scene time), like everything else in the
simulated world. Drawing fresh Gaussian noise for every pixel of every frame would cost more
than rendering, so noise comes from a bank of pre-drawn fields: each frame takes one field at a
random offset (8 fields x 33 x 33 offsets), which no per-pixel statistic can tell from fresh
noise over the few hundred frames a background model looks at.

Motion blur is a line kernel along the image motion of the view's centre during the shutter
time (:func:`motion_blur`; the world measures that motion from the head's own turn), JPEG the
codec's own round trip, so its block artefacts are those of a real camera's stream.
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

    def apply(
        self,
        image: np.ndarray,
        t: float,
        exposure: float = 1.0,
        gains: tuple[float, float, float] = (1.0, 1.0, 1.0),
    ) -> np.ndarray:
        """``image`` (BGR ``uint8``) as the camera delivers it at scene time ``t`` with
        ``exposure`` times its first exposure (the scene's ``exposure`` events) and its red,
        green and blue channels at ``gains`` times their first (``white_balance`` events)."""
        balanced = image
        if gains != (1.0, 1.0, 1.0):
            r, g, b = gains
            scaled = image * np.array([b, g, r], np.float32)  # BGR channels
            balanced = np.clip(np.rint(scaled), 0, 255).astype(np.uint8)
        out = self._exposed(balanced, t, exposure)
        quality = self.settings.jpeg_quality
        if quality:
            _, data = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, quality])
            decoded = cv2.imdecode(data, cv2.IMREAD_COLOR)
            if decoded is None:  # bytes cv2 has just encoded: not expected
                raise RuntimeError("the simulated camera's JPEG round trip failed")
            out = decoded
        return out

    def _exposed(self, image: np.ndarray, t: float, exposure: float) -> np.ndarray:
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


def motion_blur(image: np.ndarray, shift: tuple[float, float]) -> np.ndarray:
    """``image`` smeared evenly along ``shift`` (dx, dy pixels): what a sensor integrates while
    the view moves that far during its exposure. Under a pixel it is returned as it is."""
    dx, dy = shift
    length = math.hypot(dx, dy)
    if length < 1.0:
        return image
    size = 2 * math.ceil(length / 2) + 1
    kernel = np.zeros((size, size), np.float32)
    c = size // 2
    steps = max(2, math.ceil(length) + 1)
    for s in np.linspace(-0.5, 0.5, steps):
        kernel[round(c + s * dy), round(c + s * dx)] += 1.0
    kernel /= kernel.sum()
    return cv2.filter2D(image, -1, kernel, borderType=cv2.BORDER_REFLECT)
