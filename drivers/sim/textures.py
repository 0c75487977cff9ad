"""Images the simulated world is dressed in: procedural floor patterns and printed markers.

Real floors and tables are never one flat colour, and a background model that only ever saw a
flat colour would be tested too kindly. The patterns are seeded, so a scene looks the same in
every run.
"""

from __future__ import annotations

import cv2
import numpy as np

_SIZE = 512  # texture side in pixels
_MODULE_PX = 16  # texture pixels per marker module (one bit cell)


def _smooth_noise(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """Noise in [-1, 1] that varies over about ``size / cells`` pixels, tileable."""
    coarse = rng.uniform(-1.0, 1.0, (cells, cells)).astype(np.float32)
    tiled = np.tile(coarse, (3, 3))  # resize a 3x3 tiling and keep the middle: seamless edges
    big = cv2.resize(tiled, (3 * size, 3 * size), interpolation=cv2.INTER_CUBIC)
    return np.clip(big[size : 2 * size, size : 2 * size], -1.0, 1.0)


def floor_texture(kind: str, color: tuple[int, int, int], seed: int) -> np.ndarray:
    """An RGB ``uint8`` image (512 x 512) of ``kind`` wood, carpet or tiles around ``color``."""
    rng = np.random.default_rng(seed)
    n = _SIZE
    y, x = np.mgrid[0:n, 0:n].astype(np.float32) / n
    if kind == "wood":
        planks = 4  # boards across the image, each with its own shade and grain
        board = np.floor(y * planks).astype(int)
        shade = rng.uniform(-0.12, 0.12, planks)[board]
        warp = 0.04 * _smooth_noise(rng, n, 4)
        grain = np.sin(2 * np.pi * (x * 3 + (y + warp) * 37 * planks)) * 0.06
        seams = (np.abs((y * planks) % 1.0 - 0.5) > 0.49).astype(np.float32) * -0.35
        light = 1.0 + shade + grain + 0.05 * _smooth_noise(rng, n, 16) + seams
    elif kind == "carpet":
        light = 1.0 + 0.08 * _smooth_noise(rng, n, 8) + rng.normal(0.0, 0.07, (n, n))
    elif kind == "tiles":
        tiles = 4
        cell = np.floor(x * tiles).astype(int) + tiles * np.floor(y * tiles).astype(int)
        shade = rng.uniform(-0.08, 0.08, tiles * tiles)[cell]
        edge = np.minimum((x * tiles) % 1.0, (y * tiles) % 1.0) < 0.03
        light = 1.0 + shade + 0.04 * _smooth_noise(rng, n, 32) - 0.4 * edge
    else:
        raise ValueError(f"unknown floor texture {kind!r}")
    rgb = np.asarray(color, dtype=np.float32) * light[..., None]
    return np.clip(rgb, 0, 255).astype(np.uint8)


def marker_texture(dictionary: str, marker_id: int) -> np.ndarray:
    """An RGB ``uint8`` image of marker ``marker_id`` printed with a quiet zone of a quarter of
    its side on every edge (the whole image is 1.5 marker sides wide)."""
    aruco = cv2.aruco
    if not dictionary.startswith("DICT_") or not hasattr(aruco, dictionary):
        raise ValueError(f"unknown cv2.aruco dictionary {dictionary!r}")
    d = aruco.getPredefinedDictionary(getattr(aruco, dictionary))
    if marker_id >= d.bytesList.shape[0]:
        raise ValueError(f"{dictionary} has no marker {marker_id} (ids 0-{len(d.bytesList) - 1})")
    modules = d.markerSize + 2
    side = modules * _MODULE_PX
    grey = aruco.generateImageMarker(d, marker_id, side, borderBits=1)
    margin = side // 4
    grey = cv2.copyMakeBorder(grey, *(margin,) * 4, cv2.BORDER_CONSTANT, value=255)
    return cv2.cvtColor(grey, cv2.COLOR_GRAY2RGB)


def png(rgb: np.ndarray) -> bytes:
    """PNG bytes of an RGB image (MuJoCo reads textures from PNG)."""
    ok, data = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise ValueError("PNG encoding failed")
    return data.tobytes()
