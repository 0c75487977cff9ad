"""A ghost in the moving head's background (:mod:`percept.perception.view.ghosts`): someone learned
into the map of directions during calibration, gone since, is forgotten and learned anew, while
an object placed on the floor stays foreground. Synthetic frames of one view."""

from __future__ import annotations

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, rpy_matrix
from percept.perception.backgrounds import FixedBackground, ViewBackground
from percept.perception.light.maintenance import GHOST_HOLD
from percept.perception.params import BackgroundParams, ViewParams
from percept.perception.segmentation.background import BackgroundModel
from percept.perception.tracking.motion import Motion
from percept.perception.view.follow import FollowingBackground, grid_camera_matrix
from percept.perception.view.ghosts import ViewGhosts
from percept.perception.view.map.directions import direction_map
from percept.perception.view.mosaic import ViewMosaic

WIDTH, HEIGHT = 160, 120
FLOOR = (120.0, 130.0, 125.0)  # YCrCb
PERSON = (60.0, 150.0, 110.0)
OBJECT = (90.0, 170.0, 100.0)
GHOST = (slice(40, 70), slice(30, 60))  # rows, columns of the view
PLACED = (slice(40, 60), slice(100, 120))
FPS = 15.0


def _background(ghosts: bool) -> tuple[ViewBackground, CameraPose]:
    """The view background of one pose whose map learned a person at :data:`GHOST` on the
    floor, with the ghost test or without."""
    camera = CameraModel(
        np.array([[120.0, 0.0, WIDTH / 2], [0.0, 120.0, HEIGHT / 2], [0.0, 0.0, 1.0]]),
        width=WIDTH,
        height=HEIGHT,
    )
    pose = CameraPose(R=rpy_matrix((0.0, 0.6, 0.0)), t=np.array([0.0, 0.0, 0.3]))
    view_params, params = ViewParams(refine=False), BackgroundParams()
    directions, _ = direction_map([pose], camera, 1, 0.1)
    mean = np.tile(np.float32(FLOOR), (*directions.shape, 1))
    sigma = np.full_like(mean, 2.0)
    known = np.ones(directions.shape, bool)
    plain = ViewMosaic(directions, mean, sigma, known, params, view_params, 3.0)
    following = FollowingBackground(plain, camera, 1, (HEIGHT, WIDTH), view_params)
    nearest = following.view(pose, np.zeros((HEIGHT, WIDTH), np.uint8)).nearest
    rows, cols = np.divmod(nearest[GHOST], directions.cols)
    # Learned in while they stood there: every direction of the box the region covers.
    mean[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1] = PERSON
    mosaic = ViewMosaic(directions, mean, sigma, known, params, view_params, 3.0)
    following = FollowingBackground(mosaic, camera, 1, (HEIGHT, WIDTH), view_params)
    still = FixedBackground(BackgroundModel(mean[:1, :1], sigma[:1, :1], params), None)
    found = ViewGhosts(mosaic, 10.0, 50, 1) if ghosts else None
    K = grid_camera_matrix(camera, 1)
    return ViewBackground(following, still, None, None, None, K, 1, (WIDTH, HEIGHT), found), pose


def _run(background: ViewBackground, pose: CameraPose, seconds: float) -> list[np.ndarray]:
    """The foreground of each frame of the empty floor with an object at :data:`PLACED`; an
    anchor's box on the ghost for the first 4 s (born on it as the person walked off)."""
    rng = np.random.default_rng(5)
    previous = None
    out = []
    for t in np.arange(0.0, seconds, 1 / FPS):
        frame = np.tile(np.float32(FLOOR), (HEIGHT, WIDTH, 1))
        frame += rng.normal(0, 1.0, frame.shape)
        frame[PLACED] = OBJECT
        ycc = np.clip(np.rint(frame), 0, 255).astype(np.uint8)
        boxes = np.array([[30.0, 40.0, 30.0, 30.0]]) if t < 4.0 else np.zeros((0, 4))
        seen = background.foreground(ycc, pose, None, boxes, float(t))
        assert seen.upper is not None
        moved = Motion(ycc, previous, (np.zeros_like(seen.upper), seen.upper), None)
        background.learn(seen, moved, boxes, float(t))
        out.append(seen.fg)
        previous = ycc
    return out


def test_a_ghost_in_the_map_of_directions_is_forgotten_and_learned_anew() -> None:
    background, pose = _background(ghosts=True)
    fg = _run(background, pose, 7.0)
    ghost = [float(f[GHOST].mean()) for f in fg]
    placed = [float(f[PLACED].mean()) for f in fg]
    held = int(GHOST_HOLD * FPS)
    # The floor left by the person (but its edge, where the bounds take in the floor around),
    # held under the anchor.
    assert min(ghost[:held]) > 0.4
    assert max(ghost[held + 10 :]) == 0.0  # tested every 0.5 s once foreground for 3 s
    assert min(placed) == 1.0  # a placed object is no ghost, however long it stays
    mosaic = background.following.mosaic
    assert background.ghosts is not None and background.ghosts.found >= 1
    # The anchor gone (4 s), its directions are learned from the floor (learn_time 2 s).
    view = background.following.view(pose, np.zeros((HEIGHT, WIDTH), np.uint8))
    assert view.known[GHOST].all()
    cells = view.nearest[GHOST].ravel()
    assert np.abs(mosaic.mean.reshape(-1, 3)[cells] - FLOOR).max() < 1.5


def test_without_the_ghost_test_the_ghost_stays_foreground() -> None:
    background, pose = _background(ghosts=False)
    fg = _run(background, pose, 5.0)
    assert min(float(f[GHOST].mean()) for f in fg) > 0.4
