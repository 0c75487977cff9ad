"""Frames at perception's size: reduced JPEG decoding and raw YUYV straight to YCrCb."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from percept.drivers.camera.decode import decode_jpeg, yuyv_to_bgr, yuyv_to_ycrcb
from percept.kinematics.camera import grid_shape


def _yuyv(height: int, width: int, seed: int) -> np.ndarray:
    """A random limited-range YUYV frame: luma 16..235, chroma 60..195 (mostly in the BGR
    gamut)."""
    rng = np.random.default_rng(seed)
    yuyv = np.empty((height, width, 2), np.uint8)
    yuyv[..., 0] = rng.integers(16, 236, (height, width))
    yuyv[..., 1] = rng.integers(60, 196, (height, width))
    return yuyv


@pytest.mark.parametrize("step", [1, 2, 4])
def test_yuyv_to_ycrcb_matches_opencv_through_bgr(step: int) -> None:
    yuyv = _yuyv(48, 64, step)
    bgr = cv2.cvtColor(yuyv, cv2.COLOR_YUV2BGR_YUYV)
    expected = cv2.cvtColor(bgr, cv2.COLOR_BGR2YCrCb)[::step, ::step]
    got = yuyv_to_ycrcb(yuyv, step)
    assert got.shape == expected.shape == (*grid_shape(64, 48, step), 3)
    # Where BGR clips a colour outside its gamut, the round trip through BGR loses it; within
    # the gamut the two differ by rounding only.
    inside = ((bgr > 0) & (bgr < 255)).all(axis=2)[::step, ::step]
    assert inside.mean() > 0.4
    diff = np.abs(got.astype(int) - expected.astype(int))[inside]
    assert diff.max() <= 1
    assert diff.mean() < 0.35


def test_yuyv_range_is_stretched_to_full_range() -> None:
    yuyv = np.zeros((2, 4, 2), np.uint8)
    yuyv[0, :, 0], yuyv[1, :, 0] = 16, 235  # black and white
    yuyv[..., 1] = 128  # no colour
    ycc = yuyv_to_ycrcb(yuyv)
    assert ycc[0, :, 0].tolist() == [0] * 4
    assert ycc[1, :, 0].tolist() == [255] * 4
    assert (ycc[..., 1:] == 128).all()


def test_yuyv_grid_pixel_takes_the_chroma_of_its_pair() -> None:
    yuyv = np.full((1, 8, 2), 128, np.uint8)
    yuyv[0, 4, 1], yuyv[0, 5, 1] = 200, 60  # the third pair: Cb 200, Cr 60
    ycc = yuyv_to_ycrcb(yuyv, 2)  # grid columns 0, 2, 4, 6
    assert ycc[0, 2, 2] > 200 and ycc[0, 2, 1] < 60  # Cb stretched up, Cr down
    assert (ycc[0, [0, 1, 3], 1:] == 128).all()


@pytest.mark.parametrize("shape", [(4, 6, 3), (4, 5, 2), (4, 6)])
def test_yuyv_refuses_what_is_not_yuyv(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match="YUYV"):
        yuyv_to_ycrcb(np.zeros(shape, np.uint8))


def test_yuyv_to_bgr_is_opencvs() -> None:
    yuyv = _yuyv(8, 8, 3)
    assert np.array_equal(yuyv_to_bgr(yuyv), cv2.cvtColor(yuyv, cv2.COLOR_YUV2BGR_YUYV))


@pytest.mark.parametrize(("width", "height", "step"), [(640, 480, 2), (320, 200, 4), (35, 21, 2)])
def test_reduced_jpeg_decode_is_the_block_average_on_the_grid(
    width: int, height: int, step: int
) -> None:
    # a smooth image: the scaled decode of a JPEG is then close to the block average
    y, x = np.mgrid[0:height, 0:width]
    image = np.dstack([x * 255 // width, y * 255 // height, (x + y) * 127 // (width + height)])
    data = cv2.imencode(".jpg", image.astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 95])[1]
    full = decode_jpeg(data.tobytes())
    reduced = decode_jpeg(data.tobytes(), step)
    assert full is not None and reduced is not None
    assert full.shape == (height, width, 3)
    assert reduced.shape == (*grid_shape(width, height, step), 3)
    if width % step or height % step:
        return  # (odd sizes: the last grid column and row cover part of a block)
    area = cv2.resize(full, reduced.shape[1::-1], interpolation=cv2.INTER_AREA)
    assert np.abs(reduced.astype(int) - area.astype(int)).mean() < 2.0


def test_damaged_jpeg_decodes_to_none() -> None:
    assert decode_jpeg(b"\xff\xd8\xff\xe0 not a jpeg", 2) is None
