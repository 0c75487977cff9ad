"""Recording files as they are found after accidents: cut short, with flipped bits, empty, not
MCAP at all, or asked for again while kept or in use. Each is a real MCAP file written by the
daemon's own writer (:class:`percept.runtime.record.telemetry.Telemetry`, foxglove-sdk) from
rendered frames, then damaged on disk; it is read back with the readers of ``percept replay`` and
``percept stats``."""

from __future__ import annotations

import logging
import random
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.runtime.cli import main
from percept.runtime.net.messages import World, WorldObject, document
from percept.runtime.record.reader import Recording, RecordingError, read_recording
from percept.runtime.record.telemetry import Telemetry
from percept.runtime.record.writer import LOST_FAULT, lost_faults

FRAMES = 60
CHUNK = 8 * 1024  # small chunks: a few frames each, so damage costs a few frames


def _world(seq: int) -> World:
    features = {"x": 0.3 + 0.01 * seq, "y": -0.1 + 0.002 * (seq % 5)}
    features |= {"width": 0.05 + 0.001 * (seq % 3), "height": 0.04 + 0.001 * (seq % 4)}
    features |= {
        "luminance": 100.0 + seq,
        "green_red": 128.0 + seq % 6,
        "yellow_blue": 120.0 - seq % 7,
    }
    camera = {"R": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "t": [0.0, 0.0, 0.45]}
    obj = WorldObject(1, (10.0, 20.0, 30.0, 40.0), features)
    return World("a", 1.8e9 + seq / 30, seq, camera, (obj,))


def _recorded(seq: int) -> dict:
    """World model ``seq`` as it is recorded (and sent)."""
    return document(_world(seq))


def _image(seq: int) -> np.ndarray:
    """A table-top picture: a grey table, a coloured disc moving across it, sensor noise."""
    rng = np.random.default_rng(seq)
    image = np.full((120, 160, 3), 150, np.uint8)
    cv2.circle(image, (20 + 2 * seq, 60), 12, (40, 60, 200), -1)
    return cv2.add(image, rng.integers(0, 12, image.shape, dtype=np.uint8))


def write_recording(path: Path) -> Path:
    telemetry = Telemetry()
    telemetry.record(path, metadata={"robot": "a"}, chunk_size=CHUNK)
    telemetry.attach("background.npz", bytes(range(256)) * 64)
    for seq in range(FRAMES):
        wall = 1.8e9 + seq / 30
        telemetry.log_frame({"seq": seq, "t": seq / 30, "wall": wall, "joints": {}}, _image(seq))
        telemetry.log_world(_world(seq), wall)
    telemetry.close()
    return path


@pytest.fixture(scope="module")
def intact(tmp_path_factory) -> bytes:
    return write_recording(tmp_path_factory.mktemp("rec") / "a.mcap").read_bytes()


def read(path: Path) -> tuple[list[int], list[dict], Recording]:
    """Frame numbers and world models read from ``path``, and what the reader found."""
    recording = Recording(path)
    frames, worlds = [], []
    for kind, item in read_recording(path, recording):
        if kind == "frame":
            assert item.image.shape == (120, 160, 3)
            frames.append(item.inputs["seq"])
        elif kind == "world":
            worlds.append(item)
    return frames, worlds, recording


def test_an_intact_recording_reads_whole(tmp_path: Path, intact: bytes) -> None:
    path = tmp_path / "a.mcap"
    path.write_bytes(intact)
    frames, worlds, recording = read(path)
    assert frames == list(range(FRAMES))
    assert worlds == [_recorded(s) for s in range(FRAMES)]
    assert not recording.damage.any and not recording.truncated
    assert recording.metadata == {"robot": "a"}


@pytest.mark.parametrize("bits", [1, 5, 50])
def test_flipped_bits_cost_the_damaged_chunks_only(tmp_path: Path, intact: bytes, bits) -> None:
    """Whatever bits flip, reading goes on to the end, and what it returns is what was
    recorded: a chunk whose CRC fails is skipped, broken framing is searched past."""
    path = tmp_path / "a.mcap"
    rng = random.Random(bits)
    for trial in range(20):
        data = bytearray(intact)
        for _ in range(bits):
            data[rng.randrange(8, len(data))] ^= 1 << rng.randrange(8)
        path.write_bytes(data)
        frames, worlds, recording = read(path)
        assert all(w == _recorded(w["frame"]) for w in worlds), f"trial {trial}: a changed world"
        assert frames == sorted(set(frames))
        if bits == 1:  # one chunk of a few frames at most (the chunks are 8 KB, frames 3-4 KB)
            assert len(frames) >= FRAMES - 4, (trial, recording.damage)
        if len(frames) < FRAMES:
            assert recording.damage.any, (trial, recording.damage)


def test_a_flipped_bit_inside_a_chunk_is_counted(tmp_path: Path, intact: bytes) -> None:
    path = tmp_path / "a.mcap"
    data = bytearray(intact)
    jpeg = data.find(b"\xff\xd8\xff", len(data) // 3)  # a frame's JPEG (lz4 leaves it as it is)
    assert jpeg > 0
    data[jpeg + 100] ^= 0x10  # inside the JPEG data of some frame
    path.write_bytes(data)
    frames, worlds, recording = read(path)
    assert recording.damage.chunks == 1
    assert FRAMES - 4 <= len(frames) < FRAMES and len(worlds) >= FRAMES - 4
    assert not recording.truncated


def test_a_cut_recording_reads_to_its_last_complete_chunk(tmp_path: Path, intact: bytes) -> None:
    path = tmp_path / "a.mcap"
    before = 0
    for tenth in range(1, 10):
        path.write_bytes(intact[: len(intact) * tenth // 10])
        frames, worlds, recording = read(path)
        assert recording.truncated and not recording.damage.any
        assert frames == list(range(len(frames))) and len(frames) >= before
        assert worlds == [_recorded(s) for s in range(len(worlds))]
        before = len(frames)
    assert before >= FRAMES * 8 // 10


def test_stats_reads_the_objects_of_a_cut_recording(tmp_path: Path, intact: bytes) -> None:
    """(It read 0: it looked for the summary a killed daemon never writes.)"""
    from percept.perception.features.scaling import FeatureScaling

    path = tmp_path / "a.mcap"
    path.write_bytes(intact[: len(intact) // 2])
    _, worlds, _ = read(path)
    out = tmp_path / "stats.toml"
    assert main(["stats", str(path), "--out", str(out)]) == 0
    stats = FeatureScaling.load(out).stats
    assert stats["x"].n == len(worlds) >= FRAMES // 3
    assert stats["x"].mean == pytest.approx(
        np.mean([w["objects"][0]["features"]["x"] for w in worlds])
    )


@pytest.mark.parametrize("kind", ["empty", "text", "random", "a header only"])
def test_a_file_that_is_not_a_recording_exits_2(
    tmp_path: Path, intact: bytes, kind, capsys
) -> None:
    path = tmp_path / "a.mcap"
    content = {
        "empty": b"",
        "text": b"robot,x,y\na,0.3,0.1\n" * 50,
        "random": random.Random(3).randbytes(100_000),
        "a header only": intact[:5],
    }[kind]
    path.write_bytes(content)
    with pytest.raises(RecordingError, match="not an MCAP recording"):
        read(path)
    assert main(["replay", str(path), "--as-fast-as-possible"]) == 2
    assert main(["stats", str(path), "--out", str(tmp_path / "s.toml")]) == 2
    err = capsys.readouterr().err
    assert err.count("not an MCAP recording") == 2
    assert not (tmp_path / "s.toml").exists()


def test_an_existing_recording_is_kept_and_a_busy_one_is_not_opened(
    tmp_path: Path, intact: bytes, caplog
) -> None:
    """A restart with the same --record keeps the file and records to the next free name; a
    second writer while the first is writing does the same, and says the first is busy."""
    path = tmp_path / "a.mcap"
    path.write_bytes(intact)
    caplog.set_level(logging.INFO, "percept.recording")
    first = Telemetry()
    first.record(path, metadata={"robot": "a"})
    assert first.recording()["file"] == str(tmp_path / "a.1.mcap")
    assert f"{path} exists and is kept: recording to {tmp_path / 'a.1.mcap'}" in caplog.text
    second = Telemetry()
    second.record(path, metadata={"robot": "a"})
    assert second.recording()["file"] == str(tmp_path / "a.2.mcap")
    assert "(a.1.mcap: being recorded by another process)" in caplog.text
    for telemetry in (first, second):
        telemetry.log_world(_world(7), 1.8e9)
        telemetry.close()
    assert path.read_bytes() == intact
    for name in ("a.1.mcap", "a.2.mcap"):
        assert read(tmp_path / name)[1] == [_recorded(7)]


def test_channels_of_a_damaged_chunk_come_from_the_summary(tmp_path: Path, intact: bytes) -> None:
    """The first chunk holds the channel records; damaged, the summary's copies name the
    channels of the later messages. A killed file has no summary: its later messages on those
    channels are counted as lost, never guessed."""
    from io import BytesIO

    from mcap.reader import make_reader

    first = make_reader(BytesIO(intact)).get_summary().chunk_indexes[0]
    data = bytearray(intact)
    data[first.chunk_start_offset + first.chunk_length - 10] ^= 0x01  # its compressed data
    path = tmp_path / "a.mcap"
    path.write_bytes(data)
    frames, _, recording = read(path)
    assert recording.damage.chunks == 1 and recording.damage.messages == 0
    assert len(frames) >= FRAMES - 4 and frames[-1] == FRAMES - 1
    path.write_bytes(data[: first.chunk_start_offset + first.chunk_length + 20_000])
    frames, _, recording = read(path)
    assert frames == [] and recording.truncated and recording.damage.messages > 0


def _wait_until(predicate, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "not within the time allowed"
        time.sleep(0.01)


@pytest.mark.parametrize("how", ["removed", "moved", "replaced"])
def test_a_recording_whose_file_goes_away_goes_on_in_a_new_file(
    tmp_path: Path, how: str, caplog
) -> None:
    """``rm a.mcap`` (or ``mv``, or another file put in its place) while it is recorded: at the
    next flush the recorder says so (status and log) and goes on in ``a.1.mcap``, with the
    metadata and attachments; everything logged from then on is there. A moved file is closed
    whole under its new name; another file put in its place is left as it is."""
    caplog.set_level(logging.INFO, "percept.recording")
    path = tmp_path / "a.mcap"
    telemetry = Telemetry()
    telemetry.record(path, metadata={"robot": "a"}, chunk_size=CHUNK, flush_interval=0.05)
    telemetry.attach("background.npz", b"model")
    for seq in range(10):
        telemetry.log_world(_world(seq), 1.8e9 + seq)
    _wait_until(lambda: telemetry.recording()["flushed"] > time.time() - 0.04)
    other = b"somebody else's file"
    if how == "removed":
        path.unlink()
    elif how == "moved":
        path.rename(tmp_path / "kept.mcap")
    else:
        (tmp_path / "new").write_bytes(other)
        (tmp_path / "new").replace(path)
    _wait_until(lambda: telemetry.recording()["lost"])
    for seq in range(10, 20):  # after it was noticed: none of these may be lost
        telemetry.log_world(_world(seq), 1.8e9 + seq)
    status = telemetry.recording()
    telemetry.close()
    assert status["state"] == "recording" and status["file"] == str(tmp_path / "a.1.mcap")
    assert status["lost"] == [
        {
            "file": str(path),
            "how": how,
            "at": pytest.approx(time.time(), abs=5),
            "then": status["file"],
        }
    ]
    assert f"recording file {path} was {how} while recorded" in caplog.text
    faults = lost_faults(status, time.time())
    assert len(faults) == 1 and faults[0].startswith(f"recording file {path} was {how}")
    assert lost_faults(status, time.time() + LOST_FAULT + 1) == []
    _, worlds, recording = read(tmp_path / "a.1.mcap")
    assert [w["frame"] for w in worlds] == list(range(10, 20))
    assert not recording.truncated and recording.metadata == {"robot": "a"}
    assert "background.npz" in recording.attachments
    if how == "moved":
        _, worlds, recording = read(tmp_path / "kept.mcap")
        assert [w["frame"] for w in worlds] == list(range(10)) and not recording.truncated
    elif how == "replaced":
        assert path.read_bytes() == other
    else:
        assert not path.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        {
            "removed": ["a.1.mcap"],
            "moved": ["a.1.mcap", "kept.mcap"],
            "replaced": ["a.1.mcap", "a.mcap"],
        }[how]
    )
