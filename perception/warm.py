"""Compiling the perception kernels before the first frame.

numba compiles each kernel (the ``*_kernels.py`` of every stage, with
:mod:`percept.perception.compiled`) the first time it is called and keeps the machine code in
the user's cache folder. On a machine that has never run percept those
first calls take about a minute and a half of CPU (91 s for the whole warm-up on a quiet 2-core
machine, the sensory experiences' fits included), and even loading them from the cache costs
about half a second (most of it numba's first use of LLVM). :func:`warm_up` makes those first
calls on purpose: it runs the pipeline on a few frames of a small synthetic scene, the marker
detector on a picture of a tag and the footprint fit's solids, which calls every kernel with the
argument types of real frames, so each is compiled once per machine and only loaded afterwards.
``percept run`` calls it in a thread while
its devices start (a first frame that comes sooner waits for the kernel it needs), ``percept
demo`` before it starts its daemons, and CI once before the tests (``python -m
percept.perception.warm``)."""

from __future__ import annotations

import logging
import os
import threading
import time
from dataclasses import replace
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from percept.perception.evaluation.synthetic import SyntheticScene
    from percept.perception.params import PerceptionParams

log = logging.getLogger("percept.perception.warm")

FRAMES = 4
"""Frames of the synthetic scene: the first creates anchors, the next split and associate."""

_idle = threading.Event()  # set while no warm-up of warm_up_in_background runs
_idle.set()


def warm_up_in_background() -> threading.Thread:
    """Start :func:`warm_up` on a thread of its own (``warm-up``); :func:`warming` says so
    from before this returns until it ends."""
    _idle.clear()

    def run() -> None:
        try:
            warm_up()
        finally:
            _idle.set()

    thread = threading.Thread(target=run, name="warm-up", daemon=True)
    thread.start()
    return thread


def warming() -> bool:
    """Whether a warm-up of :func:`warm_up_in_background` runs now."""
    return not _idle.is_set()


def wait_warmed(stop: threading.Event) -> bool:
    """Wait until no warm-up of :func:`warm_up_in_background` runs (at once when none does);
    False when ``stop`` is set first."""
    while not _idle.wait(0.05):
        if stop.is_set():
            return False
    return True


def warm_up() -> float:
    """Compile or load every kernel; the seconds it took."""
    began = time.monotonic()
    log.info("compiling or loading the perception kernels on a synthetic scene")
    from percept.perception.evaluation.synthetic import busy_scene
    from percept.perception.landmarks.detection.detector import MarkerDetector
    from percept.perception.params import PerceptionParams
    from percept.perception.pipeline import Perception
    from percept.perception.segmentation.labelling.regions import subsample

    params = PerceptionParams()
    # A maintenance step of the light in every frame: its kernel too is compiled here.
    params = replace(
        params,
        background=replace(params.background, calibration_frames=2),
        light=replace(params.light, maintain_every=0.0),
    )
    scene = busy_scene(176, 144, 40)
    perception = Perception(params, scene.width, scene.height)
    perception.calibrate(scene.empty(2))
    for frame in range(FRAMES):
        perception.process(scene.render(frame), frame / 25.0)
    subsample(scene.render(0), 2)  # the grid of frames larger than 320x240, 176x144 has none
    _warm_moving_head(params, busy_scene(64, 48, 40))
    _warm_features()
    MarkerDetector().detect(marker_card())
    seconds = time.monotonic() - began
    log.info(
        "perception kernels ready in %.1f s (compiled code cached in %s)",
        seconds,
        os.environ["NUMBA_CACHE_DIR"],
    )
    return seconds


def _warm_moving_head(params: PerceptionParams, scene: SyntheticScene) -> None:
    """The kernels of the moving head's background (:mod:`percept.perception.view`), which a
    still camera's frames do not reach: a small scene (a calibration with poses costs a few times
    one without) seen by a camera model at poses that pan (the frames do not match the poses,
    which does not matter for the types)."""
    from percept.kinematics.camera import CameraModel
    from percept.kinematics.pose import CameraPose, rpy_matrix
    from percept.perception.colour import to_ycrcb
    from percept.perception.pipeline import Perception
    from percept.perception.tracking.anchors_kernels import may_double
    from percept.perception.tracking.permanence.memory import hidden_fraction, inside_fraction
    from percept.perception.view.cells_kernels import tiles
    from percept.perception.view.mosaic import TILE

    camera = CameraModel.from_opening_angles(1.0, 0.8, scene.width, scene.height)
    perception = Perception(params, scene.width, scene.height, camera)

    def pose(pan: float) -> CameraPose:
        return CameraPose(R=rpy_matrix((0.0, 0.5, pan)), t=np.array([0.0, 0.0, 0.5]))

    perception.calibrate(scene.empty(2), poses=[pose(0.0), pose(0.05)])
    for frame in range(FRAMES):
        perception.process(scene.render(frame), frame / 25.0, pose(0.02 * frame))
    # The previous frame brought into a turned view in boxes, around the few pixels the learning
    # asks about, and whole (the whole mask): each is asked in some frames only.
    assert perception.motion is not None
    ycc = to_ycrcb(scene.render(0))
    motion = perception.motion.update(ycc, np.eye(3))
    motion.fraction(np.array([[0.0, 0.0, 4.0, 4.0]]))
    motion.per_pixel(np.zeros(ycc.shape[:2], bool))
    motion.still()
    # What these frames do not reach, called on nothing with the types of a robot's frames: the
    # statistics and tiles of cells learned (seen quietly for seconds), and the share of a
    # remembered anchor's box under nearer ones and inside the image (reviewed once an anchor
    # went out of sight), and the boxes of two models that may be doubles.
    assert perception.following is not None
    mosaic, none = perception.following.mosaic, np.zeros(0, np.intp)
    mosaic._learning.settle(none, mosaic.mean, mosaic.sigma, mosaic.known)
    tiles(none, mosaic.directions.cols, TILE)
    hidden_fraction(np.zeros((0, 4)), np.zeros((0, 4)))
    inside_fraction(np.zeros((0, 4)), scene.width, scene.height)
    may_double(np.zeros((0, 4)), np.zeros(0, np.intp), 0.8)


def _warm_features() -> None:
    """The outlines of the solids the footprint fit measures (:mod:`percept.perception.
    footprint`), their images and the compiled box fit, which the perception core's frames do
    not reach: the daemon fits them for every anchor's sensory experience. Called with the types
    of those fits: float64 parameter rows, rims, poses and intrinsics."""
    from percept.perception.features.images_kernels import outline_images
    from percept.perception.features.newton_kernels import BALL, BOX, FRUSTUM, solid_newton
    from percept.perception.features.solids_kernels import balls, frusta

    rim, eye, origin = np.zeros((4, 2)), np.eye(3), np.zeros(3)
    frusta(np.zeros((1, 5)), rim)
    balls(np.ones((1, 3)), 0.0, 0.0, 1.0, rim)
    outline_images(np.ones((1, 4, 3)), eye, origin, eye, True)
    for kind, unknowns, measured in ((BOX, 4, 4), (BALL, 3, 5), (FRUSTUM, 5, 5)):
        target, start, ones = np.zeros(measured), np.ones(unknowns), np.ones(measured)
        steps = (1, 1e-5, 1e-3, 1e-6, 0.0)
        solid_newton(kind, target, start, 1.0, ones, ones, rim, eye, origin, eye, *steps)


def marker_card() -> np.ndarray:
    """A grey picture of one 36h11 tag on white: candidates for the marker kernels to read."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    tag = cv2.aruco.generateImageMarker(dictionary, 0, 64)
    return cv2.copyMakeBorder(tag, 48, 48, 48, 48, cv2.BORDER_CONSTANT, value=255)


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    warm_up()
