"""Recording a daemon's inputs and outputs to MCAP (read back by :mod:`.reader`).

The daemon logs everything through one :class:`Telemetry` (a foxglove-sdk context with its
channels). Sinks attach to it: an MCAP file (:func:`Telemetry.record`), a live Foxglove WebSocket
(:mod:`percept.runtime.record.view`), or both; a channel nobody listens to costs nothing, and images
are only encoded when some sink wants them.

What a recording holds (Foxglove schemas where they exist, so Foxglove and Lichtblick show it):

==============================  ===============  =============================================
topic                           schema           what
==============================  ===============  =============================================
``/camera/image``               CompressedImage  each processed frame, JPEG (``/camera/raw``:
                                                 RawImage bgr8 with ``raw_images``)
``/percept/frame``              JSON             the pipeline's inputs besides the image: seq,
                                                 monotonic ``t``, ``wall``, the joint angles at
                                                 the frame's time, their age, peer messages,
                                                 the frames whose marker search it applied
``/joints``                     JointStates      the same joint angles
``/tf``                         FrameTransform   ground -> camera pose
``/percept/world``              JSON             ``percept.world/2``, the daemon's output
``/percept/boxes``              JSON             ``percept.boxes/1`` (5 Hz)
``/percept/status``             JSON             ``percept.status/1`` (1 Hz)
``/scene``                      SceneUpdate      objects, boxes and peers in the ground frame
==============================  ===============  =============================================

plus a ``percept`` metadata record (robot, config paths) and the background model used, as the
attachment ``background.npz``. The frame and image of one frame share their log time; replay
pairs them by it.

A recording survives a crash or SIGKILL up to its last completed chunk: chunks are small and are
closed at least every ``flush_interval`` seconds. :func:`.reader.read_recording` reads such a file
to its last complete chunk and says it was cut short, and a damaged file as far as it is intact
(:mod:`.mcap_salvage`). When the disk fills up, the file is given up (it reads to its last flush,
like a killed one), the daemon goes on without recording and says so in its status, and recording
goes on in a continuation file (``a.1.mcap``, ``a.2.mcap``, ... with the same metadata and
background model) as soon as the disk takes data again (:mod:`.writer`). A file that exists is
never opened: a restarted daemon's recording takes the next free name in the same way, and says
so.
"""

from __future__ import annotations

import logging
import tempfile
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import foxglove
import numpy as np
from foxglove.channels import (
    CompressedImageChannel,
    FrameTransformChannel,
    JointStatesChannel,
    RawImageChannel,
    SceneUpdateChannel,
)
from foxglove.mcap import MCAPCompression, MCAPWriteOptions, MCAPWriter
from foxglove.messages import (
    CompressedImage,
    FrameTransform,
    JointState,
    JointStates,
    Quaternion,
    RawImage,
    Timestamp,
    Vector3,
)

from percept.kinematics.pose import quaternion
from percept.runtime.net.codec import JSON
from percept.runtime.net.messages import Boxes, Message, Status, World, document
from percept.runtime.record.scene import scene_update, timestamp
from percept.runtime.record.topics import (
    BACKGROUND_ATTACHMENT,
    CAMERA_FRAME,
    GROUND_FRAME,
    LIVE_ONLY_PREFIX,
    TOPIC_BOXES,
    TOPIC_FRAME,
    TOPIC_IMAGE,
    TOPIC_JOINTS,
    TOPIC_RAW,
    TOPIC_SCENE,
    TOPIC_STATUS,
    TOPIC_TF,
    TOPIC_WORLD,
)
from percept.runtime.record.writer import Recorder, locked, quiet_sdk_repeats

if TYPE_CHECKING:
    from percept.runtime.daemon.pipeline import Pipeline

log = logging.getLogger("percept.recording")

_FRAME_SCHEMA = {
    "type": "object",
    "title": "percept.frame/1",
    "properties": {
        "seq": {"type": "integer"},
        "t": {"type": "number"},
        "wall": {"type": "number"},
        "joints": {"type": "object"},
        "joint_age": {"type": ["number", "null"]},
        "stale_joints": {"type": "array"},
        "peer_messages": {"type": "array"},
        "marker_frames": {"type": "array"},
    },
}


def _log_json(
    channel: foxglove.Channel, message: Mapping[str, JSON] | Message | bytes, ns: int
) -> None:
    """Log a JSON message (a message as it is sent, or its encoded payload) on ``channel`` when
    something records or views it: foxglove encodes a message before it looks for sinks, and the
    daemon logs every frame whether or not anyone listens."""
    if channel.has_sinks():
        if isinstance(message, bytes):
            channel.log(message, log_time=ns)
            return
        body = dict(message) if isinstance(message, Mapping) else document(message)
        channel.log(body, log_time=ns)


def _ns(wall: float) -> int:
    return round(wall * 1e9)


def _number(value: JSON) -> float:
    """A number of a frame's JSON inputs (written by the daemon, so never anything else)."""
    if isinstance(value, int | float):
        return float(value)
    raise TypeError(f"a number expected, not {value!r}")


class Telemetry:
    """The daemon's foxglove-sdk context and channels; sinks (MCAP, WebSocket) attach to it.

    All ``log_*`` methods are cheap when no sink listens. They may be called from several
    threads (the perception thread, the 5 Hz publisher).
    """

    def __init__(self, *, raw_images: bool = False, jpeg_quality: int = 85) -> None:
        quiet_sdk_repeats()
        self.context = foxglove.Context()
        self.raw_images = raw_images
        self.jpeg_quality = jpeg_quality
        ctx = self.context
        # One image channel: raw (bgr8, for replays that match frame for frame) or JPEG.
        self._raw = RawImageChannel(TOPIC_RAW, context=ctx) if raw_images else None
        self._jpeg = None if raw_images else CompressedImageChannel(TOPIC_IMAGE, context=ctx)
        self._frame = foxglove.Channel(TOPIC_FRAME, schema=_FRAME_SCHEMA, context=ctx)
        self._joints = JointStatesChannel(TOPIC_JOINTS, context=ctx)
        self._tf = FrameTransformChannel(TOPIC_TF, context=ctx)
        self._world = foxglove.Channel(TOPIC_WORLD, schema=_json_schema(World.SCHEMA), context=ctx)
        self._boxes = foxglove.Channel(
            TOPIC_BOXES, schema=_json_schema("percept.boxes/1"), context=ctx
        )
        self._status = foxglove.Channel(
            TOPIC_STATUS, schema=_json_schema("percept.status/1"), context=ctx
        )
        self._scene = SceneUpdateChannel(TOPIC_SCENE, context=ctx)
        self._live: dict[str, CompressedImageChannel] = {}
        self._live_lock = threading.Lock()
        self._recorder: Recorder | None = None

    # -- sinks ------------------------------------------------------------------------------------

    def record(
        self,
        path: str | Path,
        *,
        metadata: Mapping[str, str],
        chunk_size: int = 256 * 1024,
        flush_interval: float = 0.5,
        retry_interval: float = 1.0,
    ) -> None:
        """Start writing an MCAP file at ``path``, or, if that exists, at the next free name
        ``<stem>.1.mcap``, ``<stem>.2.mcap``, ... (an existing file is never opened, so never
        overwritten); its chunk is closed every ``flush_interval`` seconds, and after a failed
        write (disk full) a continuation file is tried every ``retry_interval`` seconds."""
        options = MCAPWriteOptions(
            compression=MCAPCompression.Lz4,  # JPEG does not compress further; lz4 is cheap
            chunk_size=chunk_size,
            profile="percept",
            compression_threads=0,
        )

        def open_writer(file: Path) -> MCAPWriter:
            return foxglove.open_mcap(
                file,
                allow_overwrite=False,  # created exclusively: FileExistsError if it exists
                context=self.context,
                channel_filter=lambda ch: not ch.topic.startswith(LIVE_ONLY_PREFIX),
                writer_options=options,
            )

        path = Path(path)
        self._recorder = Recorder(open_writer, path, dict(metadata), flush_interval, retry_interval)
        kept = self._recorder.kept
        if kept:
            busy = [p.name for p in kept if locked(p)]
            log.warning(
                "%s exists and is kept: recording to %s%s",
                path,
                self._recorder.status()["file"],
                f" ({', '.join(busy)}: being recorded by another process)" if busy else "",
            )
        else:
            log.info("recording to %s", path)

    def attach(self, name: str, data: bytes, media_type: str = "application/octet-stream") -> None:
        """Store a file (the background model) in the recording (and its continuations)."""
        if self._recorder is not None:
            self._recorder.attach(name, data, media_type)

    def recording(self) -> dict[str, JSON] | None:
        """The recording's state for the status (None: not recording): ``state`` ("recording"
        or "failed"), ``file`` being written, ``files`` so far, ``error`` while failed, and
        ``flushed``, the wall-clock time up to which everything is on disk."""
        return None if self._recorder is None else self._recorder.status()

    def attach_background(self, pipeline: Pipeline) -> None:
        """Store the pipeline's background model, so that a replay starts from the same one."""
        if self._recorder is None:
            return
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / BACKGROUND_ATTACHMENT
            pipeline.save_background(path)
            self.attach(BACKGROUND_ATTACHMENT, path.read_bytes())

    def close(self) -> None:
        """Finish the recording (summary and footer); idempotent, never raises."""
        if self._recorder is not None:
            self._recorder.close()
            self._recorder = None

    # -- channels ---------------------------------------------------------------------------------

    def log_frame(
        self, inputs: Mapping[str, JSON], image: np.ndarray | Callable[[], np.ndarray]
    ) -> None:
        """One processed frame: its image (or how to make it: made only when recorded) and the
        pipeline's other inputs (``/percept/frame``)."""
        ns = _ns(_number(inputs["wall"]))
        stamp = timestamp(ns)
        if self._raw is not None and self._raw.has_sinks():
            image = _made(image)
            h, w = image.shape[:2]
            raw = RawImage(
                timestamp=stamp,
                frame_id=CAMERA_FRAME,
                width=w,
                height=h,
                encoding="bgr8",
                step=w * 3,
                data=np.ascontiguousarray(image).tobytes(),
            )
            self._raw.log(raw, log_time=ns)
        elif self._jpeg is not None and self._jpeg.has_sinks():
            jpeg = self._encode_jpeg(_made(image), stamp)
            if jpeg is None:
                raise RuntimeError("JPEG encoding failed")
            self._jpeg.log(jpeg, log_time=ns)
        _log_json(self._frame, inputs, ns)
        joints = inputs.get("joints")
        if isinstance(joints, dict) and joints and self._joints.has_sinks():
            states = [JointState(name=k, position=_number(v)) for k, v in sorted(joints.items())]
            self._joints.log(JointStates(timestamp=stamp, joints=states), log_time=ns)

    def log_pose(self, wall: float, R: np.ndarray, t: np.ndarray) -> None:
        """The camera pose ground -> camera at the frame's time."""
        if not self._tf.has_sinks():
            return
        ns = _ns(wall)
        x, y, z, w = quaternion(R)
        self._tf.log(
            FrameTransform(
                timestamp=timestamp(ns),
                parent_frame_id=GROUND_FRAME,
                child_frame_id=CAMERA_FRAME,
                translation=Vector3(x=float(t[0]), y=float(t[1]), z=float(t[2])),
                rotation=Quaternion(x=x, y=y, z=z, w=w),
            ),
            log_time=ns,
        )

    def log_world(self, world: World, wall: float, payload: bytes | None = None) -> None:
        """A ``percept.world/2`` message (its payload, when the caller has encoded it already)
        and the scene it describes."""
        ns = _ns(wall)
        _log_json(self._world, world if payload is None else payload, ns)
        if self._scene.has_sinks():
            self._scene.log(scene_update(world, ns), log_time=ns)

    def log_boxes(self, message: Boxes) -> None:
        _log_json(self._boxes, message, _ns(time.time()))

    def log_status(self, message: Status) -> None:
        _log_json(self._status, message, _ns(time.time()))

    def wants_live(self, name: str) -> bool:
        """Whether anyone watches the live-only image ``/live/<name>`` (draw it only then)."""
        return self._live_channel(name).has_sinks()

    def log_live_image(self, name: str, image: np.ndarray, wall: float) -> None:
        """A live-only image (debug image, top-down map), JPEG, on ``/live/<name>``."""
        channel = self._live_channel(name)
        if not channel.has_sinks():
            return
        ns = _ns(wall)
        jpeg = self._encode_jpeg(image, timestamp(ns))
        if jpeg is not None:
            channel.log(jpeg, log_time=ns)

    def _encode_jpeg(self, image: np.ndarray, stamp: Timestamp) -> CompressedImage | None:
        """``image`` as a camera-frame JPEG message (None when OpenCV cannot encode it)."""
        import cv2

        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:
            return None
        return CompressedImage(
            timestamp=stamp, frame_id=CAMERA_FRAME, data=buf.tobytes(), format="jpeg"
        )

    def _live_channel(self, name: str) -> CompressedImageChannel:
        with self._live_lock:
            channel = self._live.get(name)
            if channel is None:
                channel = self._live[name] = CompressedImageChannel(
                    LIVE_ONLY_PREFIX + name, context=self.context
                )
            return channel


def _json_schema(title: str) -> dict[str, JSON]:
    return {"type": "object", "title": title}


def _made(image: np.ndarray | Callable[[], np.ndarray]) -> np.ndarray:
    """An image, made now if it was given as how to make it."""
    return image() if callable(image) else image
