"""``percept export --ros2``: a one-minute recording (30 fps) written by the daemon's own
recorder becomes a rosbag2 that the ``rosbags`` reader reads back whole, every message on every
topic decoded and checked against the recorded world models."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from percept.runtime.cli import main
from percept.runtime.record.telemetry import Telemetry
from tests.runtime.ros2.test_ros2 import check_objects, check_tf, world
from tests.support.zenoh_rig import PROFILE

FPS, SECONDS = 30, 60
FRAMES = FPS * SECONDS


def joints(seq: int) -> dict[str, float]:
    return {"head_pan": 0.001 * seq, "head_tilt": -0.5}


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A minute of frames (tiny images: the test is about completeness, not pictures)."""
    path = tmp_path_factory.mktemp("rec") / "minute.mcap"
    telemetry = Telemetry()
    telemetry.record(path, metadata={"robot": "robot-a", "profile": str(PROFILE)})
    image = np.zeros((24, 32, 3), np.uint8)
    for seq in range(1, FRAMES + 1):
        w = world(seq)
        inputs = {"seq": seq, "t": seq / FPS, "wall": w.stamp, "joints": joints(seq)}
        telemetry.log_frame(inputs, image)
        telemetry.log_world(w, w.stamp)
    telemetry.close()
    return path


def test_a_minute_reads_back_complete(recording: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "bag"
    assert main(["export", "--ros2", str(recording), str(out)]) == 0
    assert f"/tf: {FRAMES} messages" in capsys.readouterr().out
    counts: dict[str, int] = {}
    with AnyReader([out]) as reader:
        for connection, stamp, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            seq = counts[connection.topic] = counts.get(connection.topic, 0) + 1
            w = world(seq)
            assert stamp == round(w.stamp * 1e9)
            if connection.topic == "/tf":
                check_tf(message, w)
            elif connection.topic == "/robot_a/objects":
                check_objects(message, w)
            elif connection.topic == "/robot_a/joint_states":
                assert dict(zip(message.name, message.position, strict=True)) == joints(seq)
            elif connection.topic == "/robot_a/camera/image/compressed":
                assert message.format == "jpeg" and len(message.data) > 0
            elif connection.topic == "/robot_a/camera/camera_info":
                assert (message.width, message.height) == (32, 24)
    assert counts == {
        "/tf_static": 1,
        "/tf": FRAMES,
        "/robot_a/objects": FRAMES,
        "/robot_a/joint_states": FRAMES,
        "/robot_a/camera/image/compressed": FRAMES,
        "/robot_a/camera/camera_info": FRAMES,
    }
    # ros2 bag reads MCAP whose schemas are ros2msg definitions and messages CDR.
    (mcap,) = out.glob("*.mcap")
    with mcap.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}


def test_an_existing_output_is_refused(recording: Path, tmp_path: Path) -> None:
    assert main(["export", "--ros2", str(recording), str(tmp_path)]) == 2
