"""The daemon's frame hand-over: perception takes a camera's grid image, the marker search the
full-size grey image and the recording the full image, decoded only for them."""

from __future__ import annotations

import threading
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.drivers.camera import CameraSettings, open_camera
from percept.perception.colour import to_ycrcb
from percept.perception.segmentation.grid_frame import GridFrame
from percept.runtime.daemon.markers import MarkerSearch
from percept.runtime.daemon.pipeline import perception_frame
from tests.support.polling import wait_for

pytestmark = pytest.mark.timeout(30)


def _jpeg_folder(path: Path, count: int) -> Path:
    path.mkdir()
    rng = np.random.default_rng(1)
    for i in range(count):
        image = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
        assert cv2.imwrite(str(path / f"{i:03d}.jpg"), image)
    return path


def test_grid_frames_go_to_perception_and_full_grey_images_to_the_marker_search(
    tmp_path: Path,
) -> None:
    folder = _jpeg_folder(tmp_path / "frames", 2)
    settings = CameraSettings(source=str(folder), width=64, height=48, pace="lockstep")
    with open_camera(settings, grid_step=2) as camera:
        frame = camera.wait(5.0)
    assert frame is not None
    given = perception_frame(frame)
    assert isinstance(given, GridFrame) and given.step == 2
    reduced = cv2.imread(str(folder / "000.jpg"), cv2.IMREAD_REDUCED_COLOR_2)
    assert np.array_equal(given.ycc, to_ycrcb(reduced))
    assert "image" not in frame.__dict__  # perception's share decoded no full image

    searched: list[tuple[str, tuple[int, ...]]] = []

    def detect(image: np.ndarray, pose: object) -> list:
        searched.append((threading.current_thread().name, image.shape))
        return []

    stop = threading.Event()
    search = MarkerSearch(detect, stop)  # type: ignore[arg-type]  # any pose will do
    thread = threading.Thread(target=search.run, name="markers", daemon=True)
    thread.start()
    try:
        assert search.take(frame, object())  # type: ignore[arg-type]
        assert wait_for(lambda: frame.seq in search.finished())
    finally:
        stop.set()
        thread.join(2.0)
    # the full-size grey image, made on the search's thread from the JPEG's luma: no BGR image
    assert searched == [("markers", (48, 64))]
    assert "image" not in frame.__dict__


def test_full_size_frames_go_to_perception_as_they_are(tmp_path: Path) -> None:
    folder = _jpeg_folder(tmp_path / "frames", 1)
    settings = CameraSettings(source=str(folder), width=64, height=48, pace="lockstep")
    with open_camera(settings) as camera:
        frame = camera.wait(5.0)
    assert frame is not None
    given = perception_frame(frame)
    assert isinstance(given, np.ndarray) and given.shape == (48, 64, 3)


def test_a_background_of_full_size_frames_is_given_full_frames_by_a_grid_camera(
    tmp_path: Path,
) -> None:
    """A background saved before the cameras gave grid frames keeps working: the daemon hands
    such a perception the full image (``grid`` False), which it takes."""
    from percept.perception.params import PerceptionParams
    from percept.perception.pipeline import Perception

    folder = _jpeg_folder(tmp_path / "frames", 1)
    settings = CameraSettings(source=str(folder), width=64, height=48, pace="lockstep")
    with open_camera(settings, grid_step=2) as camera:
        frame = camera.wait(5.0)
    assert frame is not None and frame.grid is not None
    params = PerceptionParams()
    params = replace(params, background=replace(params.background, calibration_frames=2))
    perception = Perception(params, 64, 48)
    perception.calibrate([frame.image, frame.image])  # full-size frames, as a saved model
    assert not perception.grid_frames
    given = perception_frame(frame, perception.grid_frames)
    assert isinstance(given, np.ndarray) and given.shape == (48, 64, 3)
    assert not perception.process(given, 0.0).skipped


def test_a_replay_gives_a_grid_background_the_recorded_images_block_averages() -> None:
    """A run calibrated on grid frames is replayed from its recorded full-size images: each is
    averaged over the grid's blocks (the same kind of frame), a full-size image otherwise."""
    from dataclasses import replace

    from percept.drivers.camera.decode import area_grid
    from percept.perception.evaluation.synthetic import busy_scene
    from percept.runtime.daemon.pipeline import Pipeline
    from percept.runtime.record.replay import _Replayer
    from percept.runtime.settings.experiment import load_experiment
    from percept.runtime.settings.profile import load_profile

    experiment = load_experiment("tabletop")
    background = replace(experiment.perception.background, calibration_frames=5)
    experiment = replace(
        experiment, perception=replace(experiment.perception, background=background)
    )
    scene = busy_scene(640, 480, 10)
    for grid in (True, False):
        pipeline = Pipeline("a", load_profile("myon"), experiment, 640, 480, joint_max_age=0.1)
        empty = scene.empty(5)
        pipeline.calibrate([GridFrame.of(area_grid(e, 2), 2) for e in empty] if grid else empty)
        image = scene.render(3)
        given = _Replayer(pipeline)._perceived(image)
        if grid:
            assert isinstance(given, GridFrame) and given.step == 2
            assert np.array_equal(given.ycc, to_ycrcb(area_grid(image, 2)))
        else:
            assert given is image
