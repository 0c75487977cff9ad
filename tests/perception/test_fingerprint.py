"""Fingerprints of the pipeline's output: every frame's masks, percepts, anchors and light
status hashed over short runs of scenes that take each way through :meth:`Perception.process`
(a still camera with the light adaptation off and on, a light switch and a change the gain
cannot explain, a moving head with and without the light adaptation, its head back at the still
calibration's pose, and a head calibrated while panning). A change of the code that is meant to
leave the results as they are must leave these hashes as they are, to the bit; one that changes
results on purpose records the new hashes here and says why.

The moving-head cases come out differently, to the bit, on the two kinds of machine the project
has been tested on, with the same code: their processors and the libraries pip resolved there
differ, and some floating-point result on the way differs with them. Which one was not found:
on the second, numpy 2.3.5 and 2.4.6, OpenCV 4.14 and 5.0, and numba compiling for a generic
processor all give its own hashes. Each case lists the hashes of both machines; a change of the
code moves a machine off its own."""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Iterable
from dataclasses import replace

import numpy as np
import pytest

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose
from percept.perception.evaluation.cubes import GREEN, RED, Cube, head_pose, render
from percept.perception.evaluation.synthetic import Blob, SyntheticScene
from percept.perception.params import PerceptionParams
from percept.perception.pipeline import FrameResult, Perception

W, H = 96, 72
FPS = 10.0


def params(light: bool, **changes: object) -> PerceptionParams:
    base = PerceptionParams()
    # The light is maintained at every frame, so its maintenance too is in the hashes.
    return replace(
        base,
        background=replace(base.background, calibration_frames=10),
        light=replace(base.light, enabled=light, maintain_every=0.0, **changes),
    )


def lit(image: np.ndarray, scale: float | np.ndarray) -> np.ndarray:
    s = np.asarray(scale, np.float32)
    if s.ndim == 2:
        s = s[..., None]
    return np.clip(image.astype(np.float32) * s, 0, 255).astype(np.uint8)


def fingerprint(results: Iterable[FrameResult]) -> str:
    """Sixteen hex digits of the SHA-256 of what the frames gave."""
    digest = hashlib.sha256()
    for r in results:
        digest.update(repr((r.t, r.skipped, r.unknown_fraction, r.light)).encode())
        percepts = r.percept_set
        for array in (percepts.boxes, percepts.histograms, percepts.counts, percepts.regions):
            digest.update(np.ascontiguousarray(array).tobytes())
        assert r.masks is not None
        m = r.masks
        for array in (m.fg, m.moved.mask(), m.regions.labels, m.pixel_classes):
            digest.update(np.ascontiguousarray(array).tobytes())
        digest.update(repr(m.class_ids).encode())
        for a in r.anchors:
            fields = (a.id, a.bbox, a.created, a.last_seen, a.in_motion, a.velocity, a.pixels)
            digest.update(repr((*fields, a.whole, a.remembered)).encode())
            digest.update(a.histograms.tobytes())
    return digest.hexdigest()[:16]


MOVING = [
    Blob((40, 200, 40), (0.18, 0.22), ((0, 0.1, 0.7), (40, 0.8, 0.6))),
    Blob((200, 80, 40), (0.15, 0.15), ((5, 0.9, 0.2), (40, 0.5, 0.3))),
]
STILL = [
    Blob((40, 40, 220), (0.2, 0.2), ((0, 0.3, 0.4), (100_000, 0.3, 0.4))),
    Blob((40, 200, 40), (0.16, 0.16), ((0, 0.7, 0.65), (100_000, 0.7, 0.65))),
]
#: Someone who stood at the right during the calibration and has gone.
GHOST = Blob((60, 50, 140), (0.3, 0.3), ((0, 0.8, 0.45), (100_000, 0.8, 0.45)))


def still_camera(
    light: bool, scales: list[float | np.ndarray], blobs: list[Blob], calibration: list[Blob]
) -> list[FrameResult]:
    """``blobs`` seen by a still camera, each frame under its light, after a calibration on
    ``calibration``."""
    scene = SyntheticScene(W, H, blobs, noise=2.0, seed=3)
    perception = Perception(params(light), W, H)
    empty = SyntheticScene(W, H, calibration, noise=2.0, seed=3)
    perception.calibrate([empty.render(100 + i) for i in range(10)])
    return [perception.process(lit(scene.render(i), s), i / FPS) for i, s in enumerate(scales)]


CAMERA = CameraModel.from_opening_angles(math.radians(60), math.radians(47), W, H)
CUBES = [Cube(RED, 0.6, 0.0), Cube(GREEN, 0.55, 0.15), Cube((200, 60, 40), 0.7, -0.2, start=8)]


def moving_head(
    light: bool, pans: list[float], scales: list[float], calibration: list[float]
) -> list[FrameResult]:
    """The cubes seen by a head at ``pans`` (radians) under ``scales`` of the light, its
    background calibrated at the ``calibration`` pans."""
    rng = np.random.default_rng(1)
    perception = Perception(params(light), W, H, CAMERA)
    poses: list[CameraPose] = [head_pose(p) for p in calibration]
    empty = [render([], 0, CAMERA, pose, rng)[0] for pose in poses]
    perception.calibrate(empty, poses=poses)
    results = []
    for f, (pan, scale) in enumerate(zip(pans, scales, strict=True)):
        image = render(CUBES, f, CAMERA, head_pose(pan), rng)[0]
        results.append(perception.process(lit(image, scale), f / FPS, head_pose(pan)))
    return results


STEADY = [1.0] * 16
SWITCH = [1.0] * 8 + [0.5] * 8
#: One lamp of two goes off: the left of the view darkens far more than the right.
UNEXPLAINED = [1.0] * 6 + [np.tile(np.linspace(0.35, 1.1, W, dtype=np.float32), (H, 1))] * 24
#: Still at the calibration's pose, panning away, and back to it.
PANS = [0.0] * 4 + [0.01 * k for k in range(1, 11)] + [0.0] * 4
PANS_SWITCH = [1.0] * 9 + [0.6] * 9


@pytest.mark.parametrize(
    ("case", "run", "expected"),
    [
        (
            "still, light off",
            lambda: still_camera(False, STEADY, MOVING, []),
            ("ba84af4b2cca1f5f",),
        ),
        ("still, light on", lambda: still_camera(True, STEADY, MOVING, []), ("b00e0b91d88ac599",)),
        ("still, a switch", lambda: still_camera(True, SWITCH, MOVING, []), ("407121724add64cc",)),
        (
            "still, unexplained",
            lambda: still_camera(True, UNEXPLAINED, STILL, []),
            ("9b62683d443ccefe",),
        ),
        (
            "still, a ghost",
            lambda: still_camera(True, STEADY, MOVING, [GHOST]),
            ("0d319a420c9f5bad",),
        ),
        (
            "head, light off",
            lambda: moving_head(False, PANS, [1.0] * 18, [0.0] * 10),
            ("8756b426c261a0e7", "091f83404750f75e"),
        ),
        (
            "head, a switch",
            lambda: moving_head(True, PANS, PANS_SWITCH, [0.0] * 10),
            ("ac716407b7c99ee0", "598e22d8a22c0276"),
        ),
        (
            "head calibrated panning",
            lambda: moving_head(True, PANS, [1.0] * 18, [0.01 * k for k in range(10)]),
            ("bbd9a8392293e908", "740c0740f16a0a5e"),
        ),
    ],
)
def test_the_pipelines_results_are_those_recorded(
    case: str, run: Callable[[], list[FrameResult]], expected: tuple[str, ...]
) -> None:
    assert fingerprint(run()) in expected, case
