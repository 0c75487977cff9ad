"""A percept recording as a rosbag2 (MCAP storage, ``ros2msg`` schemas, CDR messages) with the
topics the ROS 2 publisher sends, for ``ros2 bag info``/``play`` and the ``rosbags`` reader.

Each recorded world model gives ``/tf`` and ``objects``; with its frame (matched by sequence
number) also ``joint_states``, ``camera/image/compressed`` and, when the recording's platform
profile is readable, ``camera/camera_info``. ``/tf_static`` is written once, first. Every
message is stamped (header and bag time) with the world model's wall-clock time.
"""

from __future__ import annotations

import json
import logging
from collections import Counter, OrderedDict
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.writer import Connection

from percept.config.loader import ConfigError
from percept.kinematics.camera import CameraModel
from percept.runtime.net.messages import MessageError, World, decode
from percept.runtime.record.reader import RecordedFrame, Recording, read_recording
from percept.runtime.ros2 import messages
from percept.runtime.ros2.messages import Frames
from percept.runtime.ros2.names import full_topic
from percept.runtime.ros2.settings import TOPICS, Topic

log = logging.getLogger("percept.export")

_FRAMES_KEPT = 64  # recorded frames waiting for their world model (it is logged just after)


@dataclass
class Exported:
    """What an export wrote: messages by topic name, and world models that could not be read."""

    messages: Counter[str] = field(default_factory=Counter)
    unreadable: int = 0


def _frames_with_worlds(
    path: Path, recording: Recording, exported: Exported
) -> Iterator[tuple[World, RecordedFrame | None]]:
    """Each recorded world model with its frame (None when the frame is missing)."""
    frames: OrderedDict[int, RecordedFrame] = OrderedDict()
    waiting: dict[int, World] = {}
    for kind, item in read_recording(path, recording):
        if kind == "frame":
            seq = item.inputs.get("seq")
            if not isinstance(seq, int):
                continue
            if seq in waiting:
                yield waiting.pop(seq), item
                continue
            frames[seq] = item
            while len(frames) > _FRAMES_KEPT:
                frames.popitem(last=False)
        elif kind == "world":
            try:
                world = decode(json.dumps(item), World.SCHEMA)
            except MessageError as err:
                exported.unreadable += 1
                log.warning("%s: a world model that cannot be read is skipped: %s", path, err)
                continue
            assert isinstance(world, World)
            frame = frames.pop(world.frame, None)
            if frame is None:
                waiting[world.frame] = world
            else:
                yield world, frame
    for world in waiting.values():
        yield world, None


def _camera(recording: Recording, width: int, height: int) -> CameraModel | None:
    """The recorded robot's intrinsics from its platform profile, if it can still be read."""
    from percept.runtime.settings.profile import load_profile

    profile = recording.metadata.get("profile")
    if not profile:
        return None
    try:
        lens = load_profile(profile).camera.lens
    except ConfigError as err:
        log.warning("no camera/camera_info: the recording's profile cannot be read: %s", err)
        return None
    return CameraModel.from_lens(lens, width, height)


def export(
    path: str | Path,
    out: str | Path,
    *,
    namespace: str | None = None,
    topics: tuple[Topic, ...] = TOPICS,
) -> Exported:
    """Write recording ``path`` as the rosbag2 directory ``out`` (which must not exist);
    ``namespace`` defaults to ``/`` + the recorded robot's name."""
    path = Path(path)
    recording = Recording(path)
    exported = Exported()
    writer = Writer(Path(out), version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    connections: dict[str, Connection] = {}
    camera: CameraModel | None = None
    try:
        for world, frame in _frames_with_worlds(path, recording, exported):
            if not connections:
                ns = namespace or "/" + recording.metadata.get("robot", world.robot).replace(
                    "-", "_"
                )
                frames = Frames.of(ns)
                for topic in topics:
                    name = messages.ABSOLUTE.get(topic) or full_topic(ns, topic)
                    connections[topic] = writer.add_connection(
                        name, messages.TYPES[topic], typestore=messages.STORE
                    )
                _write(
                    writer,
                    connections,
                    exported,
                    "tf_static",
                    world.stamp,
                    messages.tf_static(world.stamp, frames),
                )
            stamp = world.stamp
            _write(writer, connections, exported, "tf", stamp, messages.tf(world, frames))
            _write(writer, connections, exported, "objects", stamp, messages.objects(world, frames))
            if frame is None:
                continue
            joints = frame.inputs.get("joints")
            if isinstance(joints, Mapping) and joints:
                angles = {str(k): float(v) for k, v in joints.items() if isinstance(v, int | float)}
                _write(
                    writer,
                    connections,
                    exported,
                    "joint_states",
                    stamp,
                    messages.joint_state(stamp, angles),
                )
            if {"camera/image/compressed", "camera/camera_info"} & set(connections):
                image: np.ndarray = frame.image
                _write(
                    writer, connections, exported, "camera/image/compressed", stamp,
                    messages.compressed_image(stamp, frames, image),
                )  # fmt: skip
                if camera is None:
                    camera = _camera(recording, image.shape[1], image.shape[0])
                if camera is not None:
                    _write(
                        writer, connections, exported, "camera/camera_info", stamp,
                        messages.camera_info(stamp, frames, camera),
                    )  # fmt: skip
    finally:
        writer.close()
    return exported


def _write(
    writer: Writer,
    connections: Mapping[str, Connection],
    exported: Exported,
    topic: str,
    stamp: float,
    message: object,
) -> None:
    connection = connections.get(topic)
    if connection is None:
        return
    writer.write(connection, round(stamp * 1e9), messages.serialize(message, connection.msgtype))
    exported.messages[connection.topic] += 1
