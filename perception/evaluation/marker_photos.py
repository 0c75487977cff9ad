"""Realistic pictures of AprilTag 36h11 markers with their exact corners, made in code.

For the marker tests and ``bench/bench_markers.py``: what a robot's camera sees of printed tags,
not the clean renders of :mod:`.markers`. Each tag is printed with a white border (one or two
cells) on a box face of cardboard colour or on a white card, stands at a random pose in front
of the camera model (tilted up to 60°), and is drawn by its homography into a supersampled image
that is averaged down (anti-aliased edges). The background is cluttered (smooth texture, dark
bars, and black squares with random bits that are no tag: false positives show there). Then a
camera's troubles, one named :data:`DEGRADATIONS` entry per picture, on top of mild sensor noise
and JPEG at quality 95 for all:

- ``clean``: only that;
- ``perspective``: every tag tilted 40-60° away from the camera;
- ``defocus``: Gaussian blur, sigma 0.6-1.2 px;
- ``motion``: a straight motion blur 2-5 px long at a random angle;
- ``noise``: sensor noise with sigma 5-10 grey levels;
- ``jpeg``: JPEG quality 50-70;
- ``light``: uneven light (a gain from 0.35 to 1 across the image, vignetting) and faces in shade;
- ``highlight``: a specular highlight (+60-130 grey levels) over part of a tag;
- ``occlusion``: objects over part of tags' white borders; one more tag has a corner of its black
  square hidden, which no quad detector can find: it is marked not ``findable``;
- ``copies``: three or four copies of one id.

Corners are in OpenCV's pixel convention (the centre of the top-left pixel at (0, 0)) and
cv2.aruco's order (top-left, top-right, bottom-right, bottom-left of the tag as printed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from percept.kinematics.camera import CameraModel
from percept.perception.landmarks.detection.detector import Marker, load_dictionary

DEGRADATIONS = (
    "clean",
    "perspective",
    "defocus",
    "motion",
    "noise",
    "jpeg",
    "light",
    "highlight",
    "occlusion",
    "copies",
)
CELLS = 8  # a 36h11 tag's black square: 6 data cells and a black border of one cell
TEXEL = 12  # texture pixels per cell
SUPERSAMPLE = 4
CARDBOARD = ((150, 190, 215), (95, 140, 180), (200, 200, 205), (60, 60, 150))  # BGR


@dataclass(frozen=True)
class TagTruth:
    """A tag in a picture: its id, its black square's corners (4, 2) and whether a quad
    detector can find it at all (its black square whole in view)."""

    id: int
    corners: np.ndarray
    findable: bool = True

    @property
    def size(self) -> float:
        """Side in pixels: the square root of the black square's area in the image."""
        x, y = self.corners[:, 0], self.corners[:, 1]
        return math.sqrt(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2)


@dataclass(frozen=True)
class TagPicture:
    """A BGR picture (after JPEG) and the tags in it."""

    image: np.ndarray
    tags: tuple[TagTruth, ...]
    degradation: str


def match(
    found: Sequence[Marker], tags: Sequence[TagTruth]
) -> tuple[list[tuple[int, int]], list[int]]:
    """Detections paired with tags: ``(tag index, detection index)`` for each tag found (a
    detection of its id whose centre is within half the tag's size of its centre), and the
    detections that pair with no tag (false positives)."""
    pairs, taken = [], set()
    for ti, tag in enumerate(tags):
        centre = tag.corners.mean(axis=0)
        near = 0.5 * float(np.ptp(tag.corners, axis=0).max())
        options = [
            (float(np.linalg.norm(m.corners.mean(axis=0) - centre)), di)
            for di, m in enumerate(found)
            if m.id == tag.id and di not in taken
        ]
        options = [o for o in options if o[0] < near]
        if options:
            di = min(options)[1]
            taken.add(di)
            pairs.append((ti, di))
    return pairs, [di for di in range(len(found)) if di not in taken]


def picture_set(
    seed: int = 0,
    per_degradation: int = 6,
    sizes: tuple[float, float] = (10.0, 120.0),
    resolutions: tuple[tuple[int, int], ...] = ((640, 480), (800, 600)),
) -> list[TagPicture]:
    """``per_degradation`` pictures of every degradation at every resolution."""
    rng = np.random.default_rng(seed)
    return [
        picture(rng, degradation, CameraModel.from_opening_angles(1.0472, 0.8172, *size), sizes)
        for size in resolutions
        for degradation in DEGRADATIONS
        for _ in range(per_degradation)
    ]


def picture(
    rng: np.random.Generator,
    degradation: str,
    camera: CameraModel,
    sizes: tuple[float, float] = (10.0, 120.0),
    tags: int = 7,
) -> TagPicture:
    """One picture of about ``tags`` tags of side ``sizes`` (pixels, log-uniform)."""
    if degradation not in DEGRADATIONS:
        raise ValueError(f"unknown degradation {degradation!r}; known: {', '.join(DEGRADATIONS)}")
    dictionary = load_dictionary("DICT_APRILTAG_36h11")
    s = SUPERSAMPLE
    big = camera.scaled(camera.width * s, camera.height * s)
    image = _background(rng, big.width, big.height)
    ids = rng.choice(400, size=tags, replace=False)
    if degradation == "copies":
        ids[: int(rng.integers(3, 5))] = ids[0]
    tilt = (0.7, 1.05) if degradation == "perspective" else (0.0, 0.7)
    # (outline box (low and high corner), 2D quad) of each print
    placed: list[tuple[tuple[np.ndarray, np.ndarray], np.ndarray]] = []
    truths: list[TagTruth] = []
    hide_corner = degradation == "occlusion"
    for tag_id in ids:
        for _ in range(40):
            side_px = math.exp(rng.uniform(math.log(sizes[0]), math.log(sizes[1])))
            pose = _pose(rng, camera, side_px, rng.uniform(*tilt))
            texture, extent, black = _print(rng, dictionary, int(tag_id), degradation)
            outline = _project(big, pose, _square(extent[1]))
            lo, hi = outline.min(axis=0), outline.max(axis=0)
            inside = lo.min() > 8 * s and hi[0] < big.width - 8 * s and hi[1] < big.height - 8 * s
            if inside and not any(_overlap((lo, hi), box, 6 * s) for box, _ in placed):
                break
        else:
            continue  # no room left for this one
        if hide_corner:  # a corner of the black square cut away: not findable
            _hide_corner(rng, texture, black)
        _warp(image, texture, extent, pose, big)
        placed.append(((lo, hi), outline))
        corners = _project(camera, pose, _square(CELLS / 2))
        truths.append(TagTruth(int(tag_id), corners, findable=not hide_corner))
        hide_corner = False
    _decoys(rng, image, [box for box, _ in placed], s)
    small = cv2.resize(image, (camera.width, camera.height), interpolation=cv2.INTER_AREA)
    small = _degrade(rng, small.astype(np.float32), degradation, truths)
    return TagPicture(small, tuple(truths), degradation)


def _pose(rng: np.random.Generator, camera: CameraModel, side_px: float, tilt: float) -> np.ndarray:
    """A 4x4 transform OpenCV camera <- tag (tag frame: x right, y up, z out, in cells) of a
    tag that looks ``side_px`` wide, tilted ``tilt`` radians from facing the camera."""
    depth = camera.fx * CELLS / side_px / max(math.sqrt(math.cos(tilt)), 0.5)
    u, v = rng.uniform(0, camera.width), rng.uniform(0, camera.height)
    centre = depth * np.array([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0])
    axis = rng.uniform(0, 2 * math.pi)
    tilt_axis = np.array([math.cos(axis), math.sin(axis), 0.0])
    R_tilt, _ = cv2.Rodrigues(tilt_axis * tilt)
    R_roll, _ = cv2.Rodrigues(np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi)]))
    # Facing the camera: the tag's z towards it, y up in the image.
    facing = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    T = np.eye(4)
    T[:3, :3] = R_tilt @ facing @ R_roll
    T[:3, 3] = centre
    return T


def _square(h: float) -> np.ndarray:
    """Corners (4, 2) of a square of half-side ``h`` in cv2.aruco's order (x right, y up)."""
    return np.array([[-h, h], [h, h], [h, -h], [-h, -h]])


def _project(camera: CameraModel, T: np.ndarray, points: np.ndarray) -> np.ndarray:
    p = np.column_stack([points, np.zeros(len(points))]) @ T[:3, :3].T + T[:3, 3]
    return (p[:, :2] / p[:, 2:]) @ camera.K[:2, :2].T + camera.K[:2, 2]


def _print(
    rng: np.random.Generator, dictionary, tag_id: int, degradation: str
) -> tuple[np.ndarray, tuple[float, float, float, float], tuple[int, int, int, int]]:
    """The texture (BGR) of a tag printed with a white border on a box face or a card, its
    extent ``(left, right, bottom, top)`` in cells about the tag's centre, and the black
    square's pixel box ``(x0, y0, x1, y1)`` in it."""
    border = int(rng.integers(1, 3))
    face = 0 if rng.random() < 0.4 else int(rng.integers(1, 4))  # 0: a white card
    pad = border + face
    tag = cv2.aruco.generateImageMarker(dictionary, tag_id, CELLS * TEXEL)
    white = cv2.copyMakeBorder(tag, *(border * TEXEL,) * 4, cv2.BORDER_CONSTANT, value=245)
    texture = cv2.cvtColor(white, cv2.COLOR_GRAY2BGR)
    if face:
        colour = CARDBOARD[int(rng.integers(len(CARDBOARD)))]
        texture = cv2.copyMakeBorder(
            texture, *(face * TEXEL,) * 4, cv2.BORDER_CONSTANT, value=colour
        )
    texture[texture < 128] = 25  # printed black is not 0
    if degradation == "light":  # a face turned away from the light
        texture = (texture * rng.uniform(0.5, 1.0)).astype(np.uint8)
    if degradation == "occlusion":
        _occlude_border(rng, texture, pad * TEXEL, border * TEXEL)
    half = CELLS / 2 + pad
    black = (pad * TEXEL, pad * TEXEL, (pad + CELLS) * TEXEL, (pad + CELLS) * TEXEL)
    return texture, (-half, half, -half, half), black


def _occlude_border(rng: np.random.Generator, texture: np.ndarray, pad: int, border: int) -> None:
    """Something over the outer part of the white border on one side (the inner half-cell
    stays white, so the black square's outline is whole)."""
    n = texture.shape[0]
    depth = int(pad - 0.5 * TEXEL) if border > TEXEL // 2 else pad - border
    depth = max(depth, 1)
    start, length = int(rng.uniform(0, n / 2)), int(rng.uniform(0.3, 0.7) * n)
    colour = tuple(int(c) for c in rng.integers(30, 200, 3))
    side = int(rng.integers(4))
    block = np.zeros_like(texture[:, :, 0], dtype=bool)
    block[start : start + length, :depth] = True
    block = np.rot90(block, side)
    texture[block] = colour


def _hide_corner(rng: np.random.Generator, texture: np.ndarray, black: tuple) -> None:
    x0, y0, x1, _ = black
    cut = int(rng.uniform(0.25, 0.45) * (x1 - x0))
    texture[y0 - TEXEL : y0 + cut, x0 - TEXEL : x0 + cut] = (60, 90, 140)


def _warp(
    image: np.ndarray, texture: np.ndarray, extent: tuple, T: np.ndarray, camera: CameraModel
) -> None:
    """Draw ``texture`` (spanning ``extent`` in the tag's plane) into ``image`` by the plane's
    homography; texture pixel centres at integers, edges at -0.5 and n - 0.5."""
    left, right, bottom, top = extent
    h, w = texture.shape[:2]
    sx, sy = (right - left) / w, (top - bottom) / h
    A = np.array([[sx, 0.0, left + 0.5 * sx], [0.0, -sy, top - 0.5 * sy], [0.0, 0.0, 1.0]])
    H = camera.K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ A
    size = (image.shape[1], image.shape[0])
    warped = cv2.warpPerspective(texture, H, size, flags=cv2.INTER_LINEAR)
    mask = cv2.warpPerspective(np.full((h, w), 255, np.uint8), H, size, flags=cv2.INTER_NEAREST)
    image[mask > 0] = warped[mask > 0]


def _overlap(a: tuple, b: tuple, gap: float) -> bool:
    return bool(np.all(a[0] - gap < b[1]) and np.all(b[0] - gap < a[1]))


def _background(rng: np.random.Generator, width: int, height: int) -> np.ndarray:
    """Smooth colour texture with dark bars: a table, a floor, a wall with things on it."""
    coarse = rng.uniform(60, 200, (6, 8, 3)).astype(np.float32)
    image = cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC)
    for _ in range(int(rng.integers(4, 9))):
        p = rng.uniform(0, 1, 2) * (width, height)
        q = p + rng.normal(0, width / 4, 2)
        colour = tuple(float(c) for c in rng.uniform(10, 80, 3))
        thickness = int(rng.uniform(0.005, 0.03) * width)
        cv2.line(image, tuple(int(v) for v in p), tuple(int(v) for v in q), colour, thickness)
    return np.clip(image, 0, 255).astype(np.uint8)


def _decoys(rng: np.random.Generator, image: np.ndarray, taken: list, s: int) -> None:
    """Black squares with random bits, no tag of the dictionary: where false positives show."""
    for _ in range(3):
        side = int(rng.uniform(15, 60) * s)
        x, y = rng.uniform(0, image.shape[1] - side), rng.uniform(0, image.shape[0] - side)
        box = (np.array([x, y]), np.array([x + side, y + side]))
        if any(_overlap(box, other, 6 * s) for other in taken):
            continue
        bits = (rng.random((6, 6)) < 0.5).astype(np.uint8) * 220 + 25
        pattern = np.full((10, 10), 245, np.uint8)
        pattern[1:9, 1:9] = 25
        pattern[2:8, 2:8] = bits
        tile = cv2.resize(pattern, (side, side), interpolation=cv2.INTER_NEAREST)
        image[int(y) : int(y) + side, int(x) : int(x) + side] = tile[:, :, None]
        taken.append(box)


def _motion_kernel(length: float, angle: float) -> np.ndarray:
    """A straight blur ``length`` pixels long: a line drawn 8 times finer, averaged down."""
    n = 2 * math.ceil(length / 2) + 1
    fine = np.zeros((8 * n, 8 * n), np.float32)
    c = 4 * n - 0.5
    d = 4 * length * np.array([math.cos(angle), math.sin(angle)])
    ends = [tuple(round(float(v)) for v in c + sign * d) for sign in (-1, 1)]
    cv2.line(fine, ends[0], ends[1], 1.0, 1)
    return cv2.resize(fine, (n, n), interpolation=cv2.INTER_AREA)


def _degrade(
    rng: np.random.Generator, image: np.ndarray, degradation: str, tags: list[TagTruth]
) -> np.ndarray:
    h, w = image.shape[:2]
    if degradation == "defocus":
        image = cv2.GaussianBlur(image, (0, 0), rng.uniform(0.6, 1.2))
    elif degradation == "motion":
        kernel = _motion_kernel(rng.uniform(2, 5), rng.uniform(0, math.pi))
        image = cv2.filter2D(image, -1, kernel / kernel.sum())
    elif degradation == "light":
        y, x = np.mgrid[0:h, 0:w].astype(np.float32)
        direction = rng.uniform(0, 2 * math.pi)
        ramp = (x / w - 0.5) * math.cos(direction) + (y / h - 0.5) * math.sin(direction)
        vignette = 1 - 0.3 * (((x - w / 2) / w) ** 2 + ((y - h / 2) / h) ** 2) * 4
        gain = (0.675 + 0.65 * ramp) * vignette
        image = image * np.clip(gain, 0.35, 1.0)[:, :, None]
    elif degradation == "highlight":
        for tag in rng.permutation(np.array(tags, dtype=object))[:3]:
            centre = tag.corners[int(rng.integers(4))] * 0.6 + tag.corners.mean(axis=0) * 0.4
            sigma = max(tag.size * rng.uniform(0.2, 0.4), 2.0)
            y, x = np.mgrid[0:h, 0:w].astype(np.float32)
            blob = np.exp(-((x - centre[0]) ** 2 + (y - centre[1]) ** 2) / (2 * sigma**2))
            image = image + rng.uniform(60, 130) * blob[:, :, None]
    noise = rng.uniform(5, 10) if degradation == "noise" else 1.5
    image = image + rng.normal(0, noise, image.shape).astype(np.float32)
    quality = int(rng.integers(50, 71)) if degradation == "jpeg" else 95
    _, data = cv2.imencode(".jpg", np.clip(image, 0, 255).astype(np.uint8), [1, quality])
    decoded = cv2.imdecode(data, cv2.IMREAD_COLOR)
    if decoded is None:
        raise RuntimeError("a JPEG just encoded did not decode")
    return decoded
