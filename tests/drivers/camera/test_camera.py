"""Camera sources on real files through real OpenCV: freshness, drops, reconnects, prompt stops."""

from __future__ import annotations

import itertools
import threading
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.config.loader import ConfigError, build
from percept.drivers.camera import (
    CameraError,
    CameraSettings,
    CameraState,
    FrameSource,
    ImageFolderCamera,
    OpenCVCamera,
    open_camera,
)
from tests.support.polling import wait_for

pytestmark = pytest.mark.timeout(30)

W, H = 64, 48
FAST = CameraSettings(source="", width=W, height=H, fps=100.0, reconnect_backoff=(0.01, 0.05))


def _images(n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(n)]


def _folder(path: Path, images: list[np.ndarray], prefix: str = "f") -> Path:
    path.mkdir(exist_ok=True)
    for i, image in enumerate(images):
        assert cv2.imwrite(str(path / f"{prefix}{i:03d}.png"), image)
    return path


def _video(path: Path, levels: list[int]) -> Path:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (W, H))
    assert writer.isOpened()
    for level in levels:
        writer.write(np.full((H, W, 3), level, np.uint8))
    writer.release()
    return path


class Flaky(FrameSource):
    """A source whose cable can be pulled: while ``broken``, reads and opens fail."""

    def __init__(self, settings: CameraSettings) -> None:
        super().__init__(settings)
        self.broken = threading.Event()
        self.opens: list[float] = []
        self.closes = 0

    def _open(self) -> None:
        self.opens.append(time.monotonic())
        if self.broken.is_set():
            raise OSError("no such device")

    def _read(self) -> np.ndarray | None:
        if self.broken.is_set():
            raise OSError("cable pulled")
        return np.zeros((H, W, 3), np.uint8)

    def _close(self) -> None:
        self.closes += 1


def test_video_file_replays_every_frame_in_order(tmp_path: Path) -> None:
    levels = [10 * i + 20 for i in range(20)]
    video = _video(tmp_path / "clip.avi", levels)
    camera = OpenCVCamera(replace(FAST, source=str(video), pace="lockstep"))
    with camera:
        frames = [camera.wait(5.0) for _ in levels]
        assert camera.wait(5.0) is None
        assert camera.state is CameraState.FINISHED
    assert all(f is not None for f in frames)
    assert [f.seq for f in frames] == list(range(len(levels)))
    assert all(a.t < b.t and a.wall <= b.wall for a, b in itertools.pairwise(frames))
    for frame, level in zip(frames, levels, strict=True):
        assert frame.image.shape == (H, W, 3) and frame.image.dtype == np.uint8
        assert abs(float(frame.image.mean()) - level) < 4  # MJPG is lossy
    assert camera.dropped == 0 and camera.status()["frames"] == len(levels)


def test_folder_replays_exact_images_in_name_order_and_loops(tmp_path: Path) -> None:
    images = _images(5)
    folder = _folder(tmp_path / "frames", images)
    (folder / "notes.txt").write_text("not an image", encoding="utf-8")
    camera = open_camera(replace(FAST, source=str(folder), pace="lockstep"))
    assert isinstance(camera, ImageFolderCamera)
    with camera:
        frames = [camera.wait(5.0) for _ in images]
        assert camera.wait(5.0) is None
    assert camera.state is CameraState.FINISHED
    assert [f.seq for f in frames] == [0, 1, 2, 3, 4]
    for frame, image in zip(frames, images, strict=True):
        np.testing.assert_array_equal(frame.image, image)

    looping = ImageFolderCamera(replace(FAST, source=str(folder), pace="lockstep", loop=True))
    with looping:
        frames = [looping.wait(5.0) for _ in range(12)]
        assert looping.state is CameraState.CONNECTED
    for i, frame in enumerate(frames):
        assert frame.seq == i
        np.testing.assert_array_equal(frame.image, images[i % 5])


def test_open_camera_picks_the_source(tmp_path: Path) -> None:
    folder = _folder(tmp_path / "frames", _images(1))
    video = _video(tmp_path / "clip.avi", [0])
    assert isinstance(open_camera(replace(FAST, source=str(folder))), ImageFolderCamera)
    file_camera = open_camera(replace(FAST, source=str(video)))
    assert isinstance(file_camera, OpenCVCamera) and not file_camera.live
    for device in ("0", "/dev/video0", "v4l2src ! videoconvert ! appsink"):
        camera = open_camera(replace(FAST, source=device))
        assert isinstance(camera, OpenCVCamera) and camera.live
    with pytest.raises(CameraError, match=r"drivers\.sim"):
        open_camera(replace(FAST, source="sim"))


def test_latest_never_hands_out_a_stale_frame_or_one_frame_twice(tmp_path: Path) -> None:
    folder = _folder(tmp_path / "one", _images(1))
    settings = replace(FAST, source=str(folder))
    stale = ImageFolderCamera(settings)
    with stale:
        # one file, no loop: one frame is captured, then the source is finished
        assert wait_for(lambda: stale.state is CameraState.FINISHED)
        time.sleep(0.3)
        assert stale.latest(max_age=0.2) is None
        assert stale.latest(max_age=60.0) is None  # refused means gone, not kept for later
    assert stale.status()["stale"] == 1

    fresh = ImageFolderCamera(settings)
    with fresh:
        assert wait_for(lambda: fresh.state is CameraState.FINISHED)
        before = time.monotonic()
        frame = fresh.latest(max_age=60.0)
        assert frame is not None and frame.seq == 0 and frame.t <= before
        assert fresh.latest(max_age=60.0) is None
        assert fresh.wait(5.0, max_age=60.0) is None  # finished: returns at once, no repeat


def test_slow_consumer_skips_to_fresh_frames_and_counts_drops(tmp_path: Path) -> None:
    folder = _folder(tmp_path / "frames", _images(3))
    max_age = 0.5
    camera = ImageFolderCamera(replace(FAST, source=str(folder), loop=True, fps=200.0))
    frames = []
    with camera:
        for _ in range(6):
            asked = time.monotonic()
            frame = camera.wait(10.0, max_age=max_age)
            assert frame is not None
            assert frame.t >= asked - max_age  # never older than asked when handed out
            frames.append(frame)
            time.sleep(0.2)  # far slower than the camera
    seqs = [f.seq for f in frames]
    assert seqs == sorted(set(seqs))
    skipped = sum(b - a - 1 for a, b in itertools.pairwise(seqs))
    status = camera.status()
    assert camera.dropped > 0 and skipped > 0
    assert skipped <= status["dropped"] + status["stale"]
    assert status["frames"] > len(frames) + camera.dropped - 2


def test_folder_in_step_with_an_epoch_stamps_each_image_at_its_time(tmp_path: Path) -> None:
    images = _images(40)
    folder = _folder(tmp_path / "frames", images)
    fps = 20.0
    epoch = time.time() + 0.3
    camera = ImageFolderCamera(replace(FAST, source=str(folder), fps=fps, epoch=epoch))
    seen = []
    with camera:
        for k in range(12):
            frame = camera.wait(5.0, max_age=1.0)
            assert frame is not None
            index = next(i for i, im in enumerate(images) if np.array_equal(im, frame.image))
            seen.append(index)
            # the image of time epoch + i / fps, stamped so (the frame's wall time)
            assert frame.wall == pytest.approx(epoch + index / fps, abs=0.002)
            if k == 5:
                time.sleep(0.4)  # a slow consumer: the images due meanwhile are skipped
    assert seen[0] == 0 and seen == sorted(set(seen))
    assert seen[6] >= 7  # not caught up one by one after the pause, but the one due now


def test_source_failing_mid_stream_reconnects_and_continues_the_sequence() -> None:
    camera = Flaky(replace(FAST, source="flaky", max_failures=3))
    with camera:
        first = camera.wait(5.0)
        assert first is not None and camera.state is CameraState.CONNECTED
        camera.broken.set()
        assert wait_for(lambda: camera.state is CameraState.RECONNECTING)
        assert wait_for(lambda: len(camera.opens) >= 3)  # keeps trying while unplugged
        status = camera.status()
        assert status["state"] == "reconnecting"
        assert "no such device" in status["error"] or "cable pulled" in status["error"]
        camera.latest(max_age=60.0)  # whatever was captured before the failure
        camera.broken.clear()
        assert wait_for(lambda: camera.state is CameraState.CONNECTED)
        after = camera.wait(5.0)
        assert after is not None and after.seq > first.seq and after.t > first.t
        assert camera.status()["reconnects"] == 1
        assert camera.closes == 1  # closed once on the failure, not on failed opens
    assert camera.closes == 2 and camera.state is CameraState.STOPPED


def test_folder_whose_files_vanish_reconnects_when_files_return(tmp_path: Path) -> None:
    folder = _folder(tmp_path / "frames", _images(3, seed=1))
    camera = ImageFolderCamera(replace(FAST, source=str(folder), loop=True, max_failures=2))
    with camera:
        before = camera.wait(5.0)
        assert before is not None
        for path in folder.iterdir():
            path.unlink()
        assert wait_for(lambda: camera.state is CameraState.RECONNECTING)
        assert wait_for(lambda: "no image files" in (camera.status()["error"] or ""))
        camera.latest(max_age=60.0)
        assert camera.state is CameraState.RECONNECTING and camera.latest(max_age=60.0) is None
        new = _images(2, seed=2)
        _folder(folder, new, prefix="g")
        assert wait_for(lambda: camera.state is CameraState.CONNECTED)
        after = camera.wait(5.0)
        assert after is not None and after.seq > before.seq
        assert any(np.array_equal(after.image, image) for image in new)


def test_reconnect_waits_back_off_exponentially() -> None:
    camera = Flaky(replace(FAST, source="flaky", reconnect_backoff=(0.05, 0.2)))
    camera.broken.set()
    with camera:
        assert wait_for(lambda: len(camera.opens) >= 5)
        assert camera.state is CameraState.RECONNECTING
    gaps = np.diff(camera.opens[:5])
    assert all(gap >= 0.9 * wait for gap, wait in zip(gaps, [0.05, 0.1, 0.2, 0.2], strict=True))


@pytest.mark.parametrize("case", ["backoff", "realtime", "lockstep"])
def test_stop_is_prompt(case: str, tmp_path: Path) -> None:
    folder = _folder(tmp_path / "frames", _images(2))
    if case == "backoff":  # waiting a minute before the next reconnect attempt
        camera: FrameSource = Flaky(replace(FAST, reconnect_backoff=(60.0, 60.0)))
        camera.broken.set()
    else:  # waiting 20 s for the next frame, or for the consumer to ask for one
        camera = ImageFolderCamera(replace(FAST, source=str(folder), fps=0.05, pace=case))
        camera.latest()
    with camera:
        assert wait_for(
            lambda: camera.state is CameraState.RECONNECTING or camera.status()["frames"] == 1
        )
        begun = time.monotonic()
        camera.stop()
        assert time.monotonic() - begun < 5.0
        assert camera.state is CameraState.STOPPED
        assert camera.status()["frames"] == (0 if case == "backoff" else 1)


def test_missing_device_keeps_reconnecting_and_missing_file_fails() -> None:
    device = OpenCVCamera(replace(FAST, source="/dev/video-percept-missing"))
    with device:
        assert wait_for(lambda: device.state is CameraState.RECONNECTING)
        assert device.latest() is None and device.wait(0.1) is None
        assert "does not exist" in device.status()["error"]
    assert device.state is CameraState.STOPPED

    missing = open_camera(replace(FAST, source="/nonexistent/clip.avi"))
    with missing:
        assert missing.wait(10.0) is None  # returns on FAILED, does not wait it out
        assert missing.state is CameraState.FAILED
        assert missing.status()["error"] == "no such video file: /nonexistent/clip.avi"


def test_gstreamer_pipeline() -> None:
    pipeline = f"videotestsrc num-buffers=30 ! video/x-raw,width={W},height={H} ! appsink"
    camera = OpenCVCamera(replace(FAST, source=pipeline))
    with camera:
        if cv2.videoio_registry.hasBackend(cv2.CAP_GSTREAMER):
            frame = camera.wait(10.0)
            assert frame is not None and frame.image.shape == (H, W, 3)
        else:
            assert wait_for(lambda: camera.state is CameraState.FAILED)
            assert camera.status()["error"] == "this OpenCV was built without GStreamer"


def test_settings_errors_name_the_key() -> None:
    with pytest.raises(ConfigError) as info:
        build(CameraSettings, {"reconnect_backoff": [2.0, 1.0]}, "op3.toml", "camera")
    assert str(info.value) == (
        "op3.toml: camera: reconnect_backoff: expected 0 < first <= largest, got [2.0, 1.0]"
    )
    with pytest.raises(ConfigError) as info:
        build(CameraSettings, {"pace": "fast"}, "op3.toml", "camera")
    assert str(info.value) == (
        'op3.toml: camera.pace: expected one of "realtime", "lockstep", got "fast"'
    )


def test_folder_of_jpegs_gives_grid_frames_and_full_images_on_request(tmp_path: Path) -> None:
    folder = tmp_path / "jpegs"
    folder.mkdir()
    images = _images(3)
    for i, image in enumerate(images):
        assert cv2.imwrite(str(folder / f"f{i}.jpg"), image)
    settings = replace(FAST, source=str(folder), pace="lockstep")
    with open_camera(settings, grid_step=2) as camera:
        frame = camera.wait(5.0)
    assert frame is not None and frame.grid is not None
    path = folder / "f0.jpg"
    assert (frame.step, frame.grid_colour) == (2, "bgr")
    reduced = cv2.imread(str(path), cv2.IMREAD_REDUCED_COLOR_2)
    assert np.array_equal(frame.grid, reduced)
    assert "image" not in frame.__dict__  # the full size is not decoded until asked for
    # The marker search's grey image is the JPEG's luma: no BGR image is made for it.
    assert np.array_equal(frame.gray, cv2.imread(str(path), cv2.IMREAD_GRAYSCALE))
    assert "image" not in frame.__dict__
    assert np.array_equal(frame.image, cv2.imread(str(path)))
    # the grey of the BGR image, but for the round trip's rounding
    through_bgr = cv2.cvtColor(frame.image, cv2.COLOR_BGR2GRAY).astype(int)
    assert np.abs(frame.gray.astype(int) - through_bgr).mean() < 0.5


def test_folder_of_pngs_gives_block_averages_on_the_grid(tmp_path: Path) -> None:
    images = _images(2)
    settings = replace(FAST, source=str(_folder(tmp_path / "pngs", images)), pace="lockstep")
    with open_camera(settings, grid_step=2) as camera:
        frame = camera.wait(5.0)
    assert frame is not None and frame.grid is not None
    area = cv2.resize(images[0], (W // 2, H // 2), interpolation=cv2.INTER_AREA)
    assert np.array_equal(frame.grid, area)
    assert np.array_equal(frame.image, images[0])
    assert np.array_equal(frame.gray, cv2.cvtColor(images[0], cv2.COLOR_BGR2GRAY))


def test_full_size_frames_have_no_grid(tmp_path: Path) -> None:
    images = _images(1)
    settings = replace(FAST, source=str(_folder(tmp_path / "pngs", images)), pace="lockstep")
    with open_camera(settings) as camera:
        frame = camera.wait(5.0)
    assert frame is not None and frame.grid is None and frame.step == 1
    assert np.array_equal(frame.image, images[0])


def test_raw_yuyv_frame_becomes_ycrcb_grid_and_bgr_on_request() -> None:
    from percept.drivers.camera.decode import yuyv_to_ycrcb
    from percept.drivers.camera.opencv import raw_capture

    rng = np.random.default_rng(5)
    yuyv = rng.integers(16, 236, (H, W, 2), dtype=np.uint8)
    flat = yuyv.reshape(1, -1)  # as some V4L2 backends hand it over
    capture = raw_capture(flat, W, H, 2)
    assert capture is not None and capture.colour == "ycrcb" and capture.step == 2
    assert np.array_equal(capture.grid, yuyv_to_ycrcb(yuyv, 2))
    assert np.array_equal(capture.full(), cv2.cvtColor(yuyv, cv2.COLOR_YUV2BGR_YUYV))
    assert capture.luma is not None
    gray = capture.luma()  # the luma stretched to the full range, as BGR2GRAY gives it
    assert gray.shape == (H, W) and gray.dtype == np.uint8
    through_bgr = cv2.cvtColor(capture.full(), cv2.COLOR_BGR2GRAY).astype(int)
    inside = ((capture.full() > 0) & (capture.full() < 255)).all(axis=2)  # not clipped
    assert np.abs(gray.astype(int) - through_bgr)[inside].max() <= 2
    assert raw_capture(flat[:, :-2], W, H, 2) is None  # a short frame is a failed read


def test_pixel_format_setting_is_checked() -> None:
    assert CameraSettings().pixel_format == "bgr"
    assert build(CameraSettings, {"pixel_format": "yuyv", "source": "/dev/video0"}, "a", "camera")
    with pytest.raises(ConfigError) as info:
        build(CameraSettings, {"pixel_format": "rgb"}, "op3.toml", "camera")
    assert str(info.value) == (
        'op3.toml: camera.pixel_format: expected one of "bgr", "yuyv", got "rgb"'
    )
    with pytest.raises(ConfigError, match='camera: pixel_format: "yuyv" is for a camera'):
        build(CameraSettings, {"pixel_format": "yuyv", "source": "frames/"}, "op3.toml", "camera")
    with pytest.raises(ConfigError, match="even width, got 641"):
        build(CameraSettings, {"pixel_format": "yuyv", "width": 641}, "op3.toml", "camera")
