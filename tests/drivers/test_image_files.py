"""Image files in the offline tools: the declared size is read from the header and checked before
decoding, each bad image is reported while the others are still read, and scores are never NaN
in JSON."""

from __future__ import annotations

import json
import struct
import tempfile
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from percept.drivers.camera.image_file import (
    DEFAULT_MAX_PIXELS,
    MAX_PIXELS_VARIABLE,
    ImageFileError,
    declared_size,
    read_image,
)
from percept.runtime.cli import main

MARKERS = Path(__file__).resolve().parents[3] / "shared" / "data" / "opencv-aruco-tutorial"


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def huge_png(path: Path, width: int, height: int, rows: int = 0) -> Path:
    """A grey PNG declaring ``width`` x ``height`` with its first ``rows`` rows of zeros: a few
    kilobytes that OpenCV would allocate the declared size for."""
    raw = zlib.compress((b"\0" * (width + 1)) * rows, 9)
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", header)
    path.write_bytes(png + _png_chunk(b"IDAT", raw) + _png_chunk(b"IEND", b""))
    return path


@settings(max_examples=40, deadline=None, database=None)
@given(
    st.integers(1, 400),
    st.integers(1, 400),
    st.sampled_from([".png", ".jpg", ".bmp", ".tiff", ".ppm", ".pgm"]),
)
def test_declared_size_is_read_from_the_header(width: int, height: int, suffix: str) -> None:
    image = np.zeros((height, width, 3), np.uint8)
    ok, data = cv2.imencode(suffix, image[:, :, 0] if suffix == ".pgm" else image)
    assert ok
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"image{suffix}"
        path.write_bytes(data.tobytes())
        assert declared_size(path) == (width, height)
        assert read_image(path).shape[:2] == (height, width)


def test_jpeg_size_is_found_after_metadata(tmp_path: Path) -> None:
    _, data = cv2.imencode(".jpg", np.zeros((30, 70, 3), np.uint8))
    exif = b"\xff\xe1" + struct.pack(">H", 5002) + b"Exif\0\0" + bytes(4994)
    path = tmp_path / "exif.jpg"
    path.write_bytes(data.tobytes()[:2] + exif + data.tobytes()[2:])
    assert declared_size(path) == (70, 30)


def test_a_huge_declared_size_is_refused_before_decoding(tmp_path: Path) -> None:
    path = huge_png(tmp_path / "huge.png", 60000, 60000)
    assert path.stat().st_size < 200
    with pytest.raises(ImageFileError, match=r"declares 60000x60000 = 3600000000 pixels"):
        read_image(path)


def test_the_limit_is_configurable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "small.png"
    cv2.imwrite(str(path), np.zeros((100, 100), np.uint8))
    assert read_image(path).shape == (100, 100, 3)
    monkeypatch.setenv(MAX_PIXELS_VARIABLE, "9999")
    with pytest.raises(
        ImageFileError, match=f"more than the limit of 9999 \\({MAX_PIXELS_VARIABLE}"
    ):
        read_image(path)
    monkeypatch.setenv(MAX_PIXELS_VARIABLE, "lots")
    with pytest.raises(ImageFileError, match="expected a positive integer"):
        read_image(path)


@pytest.mark.parametrize(
    ("content", "words"),
    [
        (b"", "not a PNG, JPEG, BMP, TIFF or PNM image"),
        (b"hello, world", "not a PNG, JPEG, BMP, TIFF or PNM image"),
        (b"\xff\xd8\xff\xd9", "damaged JPEG: no frame header"),
    ],
)
def test_not_an_image(tmp_path: Path, content: bytes, words: str) -> None:
    path = tmp_path / "x.png"
    path.write_bytes(content)
    with pytest.raises(ImageFileError, match=words):
        read_image(path)


def test_truncated_png_is_reported(tmp_path: Path) -> None:
    path = tmp_path / "cut.png"
    cv2.imwrite(str(path), np.random.default_rng(0).integers(0, 255, (200, 200), np.uint8))
    path.write_bytes(path.read_bytes()[:400])
    with pytest.raises(ImageFileError, match="cannot decode"):
        read_image(path)


@pytest.mark.skipif(not MARKERS.is_dir(), reason=f"{MARKERS} (public data) is absent")
def test_markers_reports_bad_images_and_reads_the_rest(tmp_path: Path, capsys) -> None:
    good = str(MARKERS / "singlemarkersoriginal.jpg")
    huge = str(huge_png(tmp_path / "huge.png", 60000, 60000))
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(40))
    argv = ["markers", good, huge, str(broken), good, "--dict", "DICT_6X6_250", "--json"]
    assert main(argv) == 1  # some images failed
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [line["image"] for line in lines] == [good, huge, str(broken), good]
    assert "60000x60000" in lines[1]["error"] and "error" in lines[2]
    assert len(lines[0]["markers"]) == len(lines[3]["markers"]) > 0


def _foreground_folders(tmp_path: Path) -> tuple[Path, Path]:
    gt, masks = tmp_path / "groundtruth", tmp_path / "masks"
    gt.mkdir()
    masks.mkdir()
    label = np.zeros((60, 80), np.uint8)
    label[10:30, 20:50] = 255
    for n in range(1, 5):
        cv2.imwrite(str(gt / f"gt{n:06d}.png"), label)
        cv2.imwrite(str(masks / f"{n:06d}.png"), label)
    return gt, masks


def test_eval_foreground_skips_bad_images(tmp_path: Path, capsys) -> None:
    gt, masks = _foreground_folders(tmp_path)
    # A decompression bomb: 2 kB of PNG declaring 30000x30000 (900 MB decoded) ...
    huge_png(gt / "gt000002.png", 30000, 30000, rows=50)
    # ... and a corrupt one (the AttributeError of issue 14).
    (masks / "000003.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(100))
    assert main(["eval", "foreground", "--gt", str(gt), "--masks", str(masks)]) == 1
    captured = capsys.readouterr()
    scores = json.loads(captured.out)
    assert scores["frames"] == 2 and scores["f1"] == 1.0
    assert [s["frame"] for s in scores["skipped"]] == ["2", "3"]
    assert "30000x30000" in scores["skipped"][0]["error"]
    assert "frame 3 skipped" in captured.err


def test_eval_foreground_of_no_foreground_is_null_with_a_reason(tmp_path: Path, capsys) -> None:
    gt, masks = _foreground_folders(tmp_path)
    for folder in (gt, masks):
        for path in folder.iterdir():
            cv2.imwrite(str(path), np.zeros((60, 80), np.uint8))
    assert main(["eval", "foreground", "--gt", str(gt), "--masks", str(masks)]) == 0
    out = capsys.readouterr().out
    assert "NaN" not in out
    scores = json.loads(out)
    assert scores["precision"] is None and scores["recall"] is None and scores["f1"] is None
    assert scores["undefined"]["recall"] == "no foreground in the ground truth"
    assert scores["specificity"] == 1.0


def test_eval_tracking_of_empty_ground_truth_is_null_with_a_reason(tmp_path: Path, capsys) -> None:
    gt, tracks = tmp_path / "gt.txt", tmp_path / "tracks.txt"
    gt.write_text("", encoding="utf-8")
    tracks.write_text("1,1,10,10,20,20,1,-1,-1,-1\n", encoding="utf-8")
    assert main(["eval", "tracking", "--gt", str(gt), "--tracks", str(tracks)]) == 0
    out = capsys.readouterr().out
    assert "NaN" not in out
    scores = json.loads(out)
    assert scores["mota"] is None and scores["idr"] is None
    assert scores["undefined"]["mota"] == "no ground-truth boxes"
    assert scores["idf1"] == 0.0 and scores["fp"] == 1


def test_default_limit_fits_the_largest_camera() -> None:
    from percept.config.loader import fields_doc
    from percept.drivers.camera.settings import CameraSettings

    sides = {key: kind for key, kind, _, _ in fields_doc(CameraSettings)}
    assert sides["width"] == "an integer 16-8192" and sides["height"] == "an integer 16-8192"
    assert DEFAULT_MAX_PIXELS == 8192 * 8192


def test_calibrate_camera_skips_unreadable_images(tmp_path: Path, capsys) -> None:
    huge = str(huge_png(tmp_path / "huge.png", 60000, 60000))
    assert main(["calibrate-camera", huge, "--out", str(tmp_path / "cam.yml")]) == 2
    err = capsys.readouterr().err
    assert "skipped: " in err and "60000x60000" in err
    assert "none of the images could be read" in err


def test_camera_folder_passes_over_a_bad_image(tmp_path: Path, caplog) -> None:
    from dataclasses import replace

    from percept.drivers.camera import CameraState, ImageFolderCamera
    from percept.drivers.camera.settings import CameraSettings

    folder = tmp_path / "frames"
    folder.mkdir()
    images = [np.full((48, 64, 3), v, np.uint8) for v in (10, 200)]
    cv2.imwrite(str(folder / "f0.png"), images[0])
    huge_png(folder / "f1.png", 60000, 60000)
    cv2.imwrite(str(folder / "f2.png"), images[1])
    settings = CameraSettings(source=str(folder), width=64, height=48, fps=100.0)
    camera = ImageFolderCamera(replace(settings, pace="lockstep"))
    with camera:
        frames = [camera.wait(5.0) for _ in images]
        assert camera.wait(5.0) is None
    assert camera.state is CameraState.FINISHED
    assert [int(f.image[0, 0, 0]) for f in frames] == [10, 200]
    assert "skipped: " in caplog.text and "f1.png: declares 60000x60000" in caplog.text
