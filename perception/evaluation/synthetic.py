"""Synthetic table-top scenes with known truth, for tests and benchmarks.

A scene is a textured background with coloured, striped boxes or ellipses that appear, move
along straight segments between keyframes, hide and come back, drawn in list order (later blobs
occlude earlier ones), plus Gaussian camera noise. Positions and sizes are fractions of the image,
so one scene renders at 176x144 and at 640x480 alike. :meth:`SyntheticScene.truth` gives each
visible blob's full box (occluded parts included, as in MOTChallenge ground truth).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Blob:
    """One object: colour, size, where it is at some frames, and when it is hidden."""

    colour: tuple[int, int, int]
    """BGR."""
    size: tuple[float, float]
    """Width and height as fractions of the image's."""
    keyframes: tuple[tuple[int, float, float], ...]
    """(frame, centre x, centre y): linear in between; absent outside the first..last frame."""
    hidden: tuple[tuple[int, int], ...] = ()
    """Frame ranges [start, stop) in which it is not drawn."""
    ellipse: bool = False

    def centre(self, frame: int) -> tuple[float, float] | None:
        """Centre (fractions) at ``frame``, or None when the blob is not in the scene."""
        if frame < self.keyframes[0][0] or frame > self.keyframes[-1][0]:
            return None
        if any(a <= frame < b for a, b in self.hidden):
            return None
        frames = [k[0] for k in self.keyframes]
        x = float(np.interp(frame, frames, [k[1] for k in self.keyframes]))
        y = float(np.interp(frame, frames, [k[2] for k in self.keyframes]))
        return x, y


class SyntheticScene:
    """Renders frames of a list of blobs over a textured background."""

    def __init__(
        self,
        width: int,
        height: int,
        blobs: list[Blob],
        noise: float = 2.0,
        seed: int = 0,
    ) -> None:
        self.width, self.height = width, height
        self.blobs = blobs
        self.noise = noise
        self.seed = seed
        self.background = _texture(width, height, seed)

    def box(self, blob: Blob, frame: int) -> tuple[int, int, int, int] | None:
        """(left, top, width, height) in pixels of ``blob`` at ``frame``, or None."""
        c = blob.centre(frame)
        if c is None:
            return None
        w, h = round(blob.size[0] * self.width), round(blob.size[1] * self.height)
        left = round(c[0] * self.width - w / 2)
        top = round(c[1] * self.height - h / 2)
        return left, top, w, h

    def render(self, frame: int, noise: bool = True) -> np.ndarray:
        """The BGR image at ``frame``."""
        image = self.background.copy()
        for blob in self.blobs:
            box = self.box(blob, frame)
            if box is not None:
                _draw(image, blob, box)
        if noise and self.noise > 0:
            rng = np.random.default_rng((self.seed, frame + 1_000_000))
            grain = rng.normal(0.0, self.noise, image.shape).astype(np.float32)
            image = cv2.add(image.astype(np.float32), grain)
            image = np.clip(image, 0, 255).astype(np.uint8)
        return image

    def truth(self, frame: int) -> list[tuple[int, int, int, int, int]]:
        """(id, left, top, width, height) of every blob in view; ids count from 1."""
        out = []
        for i, blob in enumerate(self.blobs):
            box = self.box(blob, frame)
            if box is not None:
                out.append((i + 1, *box))
        return out

    def empty(self, frames: int) -> list[np.ndarray]:
        """``frames`` noisy images of the background alone (for calibration)."""
        saved, self.blobs = self.blobs, []
        try:
            return [self.render(-1 - i) for i in range(frames)]
        finally:
            self.blobs = saved


def _texture(width: int, height: int, seed: int) -> np.ndarray:
    """A table-like background: smooth colour variation, wood-grain stripes, a few marks."""
    rng = np.random.default_rng(seed)
    coarse = rng.integers(90, 170, (6, 8, 3)).astype(np.uint8)
    image = cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC)
    grain = (8 * np.sin(np.arange(height) / max(height, 1) * 60.0)).astype(np.int16)
    image = np.clip(image.astype(np.int16) + grain[:, None, None], 0, 255).astype(np.uint8)
    for _ in range(12):
        x, y = int(rng.integers(0, width)), int(rng.integers(0, height))
        r = max(1, int(rng.integers(1, max(2, width // 60))))
        cv2.circle(image, (x, y), r, [int(v) for v in rng.integers(40, 220, 3)], -1)
    return image


def _draw(image: np.ndarray, blob: Blob, box: tuple[int, int, int, int]) -> None:
    """The blob in its colour, with darker stripes so that its histograms have some width."""
    left, top, w, h = box
    mask = np.zeros(image.shape[:2], np.uint8)
    if blob.ellipse:
        centre = (left + w // 2, top + h // 2)
        cv2.ellipse(mask, centre, (max(w // 2, 1), max(h // 2, 1)), 0, 0, 360, 255, -1)
    else:
        cv2.rectangle(mask, (left, top), (left + w - 1, top + h - 1), 255, -1)
    colour = np.array(blob.colour, np.float32)
    stripes = np.zeros(image.shape[:2], bool)
    period = max(4, w // 4)
    stripes[:, max(left, 0) :: period] = True
    stripes[:, max(left, 0) + 1 :: period] = True
    inside = mask > 0
    image[inside & ~stripes] = colour.astype(np.uint8)
    image[inside & stripes] = (colour * 0.75).astype(np.uint8)


def busy_scene(width: int, height: int, frames: int, seed: int = 0) -> SyntheticScene:
    """Eight objects: four still, and four that rest for the first tenth of the frames, then move
    to and fro across the image, two of them over still ones."""
    colours = [
        (40, 40, 220),
        (40, 200, 40),
        (220, 60, 40),
        (30, 200, 230),
        (200, 40, 200),
        (230, 220, 40),
        (40, 120, 250),
        (250, 250, 250),
    ]
    spots = [(0.15, 0.25), (0.45, 0.25), (0.75, 0.25), (0.3, 0.75)]
    blobs = [
        Blob(colours[i], (0.09, 0.12), ((0, *spots[i]), (frames, *spots[i])), ellipse=i % 2 == 1)
        for i in range(4)
    ]
    moving = [
        ((0.05, 0.3), (0.95, 0.3)),
        ((0.95, 0.7), (0.05, 0.7)),
        ((0.6, 0.1), (0.6, 0.9)),
        ((0.85, 0.85), (0.2, 0.2)),
    ]
    for i, (a, b) in enumerate(moving):
        keys = ((0, *a), (frames // 10, *a), (frames // 2, *b), (frames, *a))
        blobs.append(Blob(colours[4 + i], (0.08, 0.1), keys, ellipse=i % 2 == 0))
    return SyntheticScene(width, height, blobs, seed=seed)
