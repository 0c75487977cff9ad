"""Recording a daemon's inputs and outputs to MCAP, and reading them back.

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
``/percept/world``              JSON             ``percept.world/1``, the daemon's output
``/percept/boxes``              JSON             ``percept.boxes/1`` (5 Hz)
``/percept/status``             JSON             ``percept.status/1`` (1 Hz)
``/scene``                      SceneUpdate      objects, boxes and peers in the ground frame
==============================  ===============  =============================================

plus a ``percept`` metadata record (robot, config paths) and the background model used, as the
attachment ``background.npz``. The frame and image of one frame share their log time; replay
pairs them by it.

A recording survives a crash or SIGKILL up to its last completed chunk: chunks are small and are
closed at least every ``flush_interval`` seconds. :func:`read_recording` reads such a file to its
last complete chunk and says it was cut short, and a damaged file as far as it is intact
(:mod:`percept.runtime.record.mcap_salvage`). When the disk fills up, the file is given up (it reads
to its last flush, like a killed one), the daemon goes on without recording and says so in its
status, and recording goes on in a continuation file (``a.1.mcap``, ``a.2.mcap``, ... with the same
metadata and background model) as soon as the disk takes data again. A file that exists is never
opened: a restarted daemon's recording takes the next free name in the same way, and says so.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import itertools
import json
import logging
import os
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from percept.runtime.net.messages import Boxes, Message, Status, World, document

if TYPE_CHECKING:
    from percept.runtime.record.mcap_salvage import Damage

log = logging.getLogger("percept.recording")

TOPIC_IMAGE = "/camera/image"
TOPIC_RAW = "/camera/raw"
TOPIC_FRAME = "/percept/frame"
TOPIC_JOINTS = "/joints"
TOPIC_TF = "/tf"
TOPIC_WORLD = "/percept/world"
TOPIC_BOXES = "/percept/boxes"
TOPIC_STATUS = "/percept/status"
TOPIC_SCENE = "/scene"
LIVE_ONLY_PREFIX = "/live/"  # debug images and the map: shown live, never recorded

BACKGROUND_ATTACHMENT = "background.npz"
GROUND_FRAME = "ground"
CAMERA_FRAME = "camera"

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


def _log_json(channel: Any, message: Mapping[str, Any] | Message | bytes, ns: int) -> None:
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


class Telemetry:
    """The daemon's foxglove-sdk context and channels; sinks (MCAP, WebSocket) attach to it.

    All ``log_*`` methods are cheap when no sink listens. They may be called from several
    threads (the perception thread, the 5 Hz publisher).
    """

    def __init__(self, *, raw_images: bool = False, jpeg_quality: int = 85) -> None:
        import foxglove
        from foxglove.channels import (
            CompressedImageChannel,
            FrameTransformChannel,
            JointStatesChannel,
            RawImageChannel,
            SceneUpdateChannel,
        )

        _quiet_sdk_repeats()
        self.context = foxglove.Context()
        self.raw_images = raw_images
        self.jpeg_quality = jpeg_quality
        ctx = self.context
        self._image = (
            RawImageChannel(TOPIC_RAW, context=ctx)
            if raw_images
            else CompressedImageChannel(TOPIC_IMAGE, context=ctx)
        )
        self._frame = foxglove.Channel(TOPIC_FRAME, schema=_FRAME_SCHEMA, context=ctx)
        self._joints = JointStatesChannel(TOPIC_JOINTS, context=ctx)
        self._tf = FrameTransformChannel(TOPIC_TF, context=ctx)
        self._world = foxglove.Channel(
            TOPIC_WORLD, schema=_json_schema("percept.world/1"), context=ctx
        )
        self._boxes = foxglove.Channel(
            TOPIC_BOXES, schema=_json_schema("percept.boxes/1"), context=ctx
        )
        self._status = foxglove.Channel(
            TOPIC_STATUS, schema=_json_schema("percept.status/1"), context=ctx
        )
        self._scene = SceneUpdateChannel(TOPIC_SCENE, context=ctx)
        self._live: dict[str, Any] = {}
        self._live_lock = threading.Lock()
        self._recorder: _Recorder | None = None

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
        import foxglove
        from foxglove.mcap import MCAPCompression, MCAPWriteOptions

        options = MCAPWriteOptions(
            compression=MCAPCompression.Lz4,  # JPEG does not compress further; lz4 is cheap
            chunk_size=chunk_size,
            profile="percept",
            compression_threads=0,
        )

        def open_writer(file: Path) -> Any:
            return foxglove.open_mcap(
                file,
                allow_overwrite=False,  # created exclusively: FileExistsError if it exists
                context=self.context,
                channel_filter=lambda ch: not ch.topic.startswith(LIVE_ONLY_PREFIX),
                writer_options=options,
            )

        path = Path(path)
        self._recorder = _Recorder(
            open_writer, path, dict(metadata), flush_interval, retry_interval
        )
        kept = self._recorder.kept
        if kept:
            busy = [p.name for p in kept if _locked(p)]
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

    def recording(self) -> dict[str, Any] | None:
        """The recording's state for the status (None: not recording): ``state`` ("recording"
        or "failed"), ``file`` being written, ``files`` so far, ``error`` while failed, and
        ``flushed``, the wall-clock time up to which everything is on disk."""
        return None if self._recorder is None else self._recorder.status()

    def attach_background(self, pipeline: Any) -> None:
        """Store the pipeline's background model, so that a replay starts from the same one."""
        if self._recorder is None:
            return
        import tempfile

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

    def log_frame(self, inputs: Mapping[str, Any], image: np.ndarray) -> None:
        """One processed frame: its image and the pipeline's other inputs (``/percept/frame``)."""
        from foxglove.messages import (
            CompressedImage,
            JointState,
            JointStates,
            RawImage,
            Timestamp,
        )

        ns = _ns(inputs["wall"])
        stamp = Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)
        if self._image.has_sinks():
            if self.raw_images:
                h, w = image.shape[:2]
                msg = RawImage(
                    timestamp=stamp,
                    frame_id=CAMERA_FRAME,
                    width=w,
                    height=h,
                    encoding="bgr8",
                    step=w * 3,
                    data=np.ascontiguousarray(image).tobytes(),
                )
            else:
                import cv2

                ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
                if not ok:
                    raise RuntimeError("JPEG encoding failed")
                msg = CompressedImage(
                    timestamp=stamp, frame_id=CAMERA_FRAME, data=buf.tobytes(), format="jpeg"
                )
            self._image.log(msg, log_time=ns)
        _log_json(self._frame, inputs, ns)
        joints = inputs.get("joints") or {}
        if joints and self._joints.has_sinks():
            states = [JointState(name=k, position=float(v)) for k, v in sorted(joints.items())]
            self._joints.log(JointStates(timestamp=stamp, joints=states), log_time=ns)

    def log_pose(self, wall: float, R: np.ndarray, t: np.ndarray) -> None:
        """The camera pose ground -> camera at the frame's time."""
        if not self._tf.has_sinks():
            return
        from foxglove.messages import FrameTransform, Quaternion, Timestamp, Vector3

        ns = _ns(wall)
        x, y, z, w = _quaternion(R)
        self._tf.log(
            FrameTransform(
                timestamp=Timestamp(ns // 1_000_000_000, ns % 1_000_000_000),
                parent_frame_id=GROUND_FRAME,
                child_frame_id=CAMERA_FRAME,
                translation=Vector3(x=float(t[0]), y=float(t[1]), z=float(t[2])),
                rotation=Quaternion(x=x, y=y, z=z, w=w),
            ),
            log_time=ns,
        )

    def log_world(self, world: World, wall: float, payload: bytes | None = None) -> None:
        """A ``percept.world/1`` message (its payload, when the caller has encoded it already)
        and the scene it describes."""
        ns = _ns(wall)
        _log_json(self._world, world if payload is None else payload, ns)
        if self._scene.has_sinks():
            self._scene.log(_scene_update(world, ns), log_time=ns)

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
        import cv2
        from foxglove.messages import CompressedImage, Timestamp

        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if ok:
            ns = _ns(wall)
            msg = CompressedImage(
                timestamp=Timestamp(ns // 1_000_000_000, ns % 1_000_000_000),
                frame_id=CAMERA_FRAME,
                data=buf.tobytes(),
                format="jpeg",
            )
            channel.log(msg, log_time=ns)

    def _live_channel(self, name: str) -> Any:
        from foxglove.channels import CompressedImageChannel

        with self._live_lock:
            channel = self._live.get(name)
            if channel is None:
                channel = self._live[name] = CompressedImageChannel(
                    LIVE_ONLY_PREFIX + name, context=self.context
                )
            return channel


def _json_schema(title: str) -> dict[str, Any]:
    return {"type": "object", "title": title}


class _Recorder:
    """An MCAP file being written, on a thread of its own.

    The current chunk is closed every ``flush_interval`` seconds, so a crash loses at most that
    much. A write that fails (disk full: foxglove-sdk then refuses every later write to the
    file) gives the file up: it is closed as far as it goes and reads to its last flush. Every
    ``retry_interval`` seconds the disk is probed, and once it takes data again recording goes
    on in a continuation file with the same metadata and attachments.

    Every file, the first and the continuations, takes the first free name of ``path``,
    ``<stem>.1.mcap``, ``<stem>.2.mcap``, ...: it is created exclusively (an existing file, an
    earlier recording or another process's, is never opened) and locked (``flock``) while it
    is written, which tells a second process that it is in use.
    """

    def __init__(
        self,
        open_writer: Callable[[Path], Any],
        path: Path,
        metadata: dict[str, str],
        flush_interval: float,
        retry_interval: float,
    ) -> None:
        self._open_writer = open_writer
        self._first = path
        self._metadata = metadata
        self._attachments: list[tuple[str, bytes, str]] = []
        self._flush_interval = flush_interval
        self._retry_interval = retry_interval
        self._lock = threading.Lock()
        self._held: int | None = None  # the descriptor holding the current file's flock
        self._files: list[Path] = []
        self.kept: list[Path] = []  # existing files the first one was not written to
        self._writer = self._start()  # a first file that cannot be opened is an error
        self._error: str | None = None
        self._flushed = time.time()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mcap recorder", daemon=True)
        self._thread.start()

    def _start(self) -> Any:
        """Open the first free name, lock it, and write the metadata and attachments."""
        if self._first.is_dir():  # not a recording to keep: a mistake
            raise IsADirectoryError(errno.EISDIR, "a folder, not a file", str(self._first))
        for path in recording_names(self._first):
            if not path.exists():
                try:
                    writer = self._open_writer(path)
                    break
                except FileExistsError:  # created by another process since the look
                    pass
            if not self._files:
                self.kept.append(path)
        self._files.append(path)
        self._release()
        try:
            self._held = _lock(path)
            writer.write_metadata("percept", dict(self._metadata))
            for name, data, media_type in self._attachments:
                _attach(writer, name, data, media_type)
        except Exception:
            _close_quietly(writer)
            raise
        return writer

    def _release(self) -> None:
        if self._held is not None:
            os.close(self._held)  # the flock goes with the descriptor
            self._held = None

    def attach(self, name: str, data: bytes, media_type: str) -> None:
        with self._lock:
            self._attachments.append((name, data, media_type))
            if self._writer is not None:
                try:
                    _attach(self._writer, name, data, media_type)
                except Exception as err:
                    self._fail(err)

    def status(self) -> dict[str, Any]:
        with self._lock:
            return {
                "state": "recording" if self._writer is not None else "failed",
                "file": str(self._files[-1]),
                "files": [str(f) for f in self._files],
                "error": self._error,
                "flushed": round(self._flushed, 3),
            }

    def _run(self) -> None:
        next_retry = 0.0
        while not self._stop.wait(self._flush_interval):
            with self._lock:
                if self._writer is not None:
                    try:
                        self._writer.flush()
                        self._flushed = time.time()
                    except Exception as err:  # a full disk must not stop perception
                        self._fail(err)
                        next_retry = time.monotonic() + self._retry_interval
                elif time.monotonic() >= next_retry:
                    self._retry()
                    next_retry = time.monotonic() + self._retry_interval

    def _fail(self, err: Exception) -> None:
        """Give the current file up (lock held)."""
        self._error = _disk_problem(self._files[-1].parent) or _words(err)
        log.error(
            "recording to %s failed: %s; the file keeps everything up to %s; recording goes on "
            "in a new file when the disk takes data again",
            self._files[-1],
            self._error,
            time.strftime("%H:%M:%S", time.localtime(self._flushed)),
        )
        _close_quietly(self._writer)
        self._writer = None
        self._release()

    def _retry(self) -> None:
        """Open a continuation file if the disk takes data again (lock held)."""
        problem = _disk_problem(self._first.parent)
        if problem is not None:
            self._error = problem
            return
        files = len(self._files)
        writer = None
        try:
            writer = self._start()
            writer.flush()
        except Exception as err:
            self._error = _words(err)
            _close_quietly(writer)
            if len(self._files) > files:  # created, but it does not take data: not kept
                self._files.pop().unlink(missing_ok=True)
                self._release()
            return
        self._writer, self._error, self._flushed = writer, None, time.time()
        log.warning("recording goes on in %s", self._files[-1])

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        with self._lock:
            if self._writer is not None:
                try:
                    self._writer.close()
                    log.info("recording closed")
                except Exception as err:
                    log.error("closing the recording %s failed: %s", self._files[-1], err)
                self._writer = None
            self._release()


class _Repeats(logging.Filter):
    """Lets each distinct line through once every ``interval`` seconds: after a failed write
    foxglove-sdk logs every message the file refuses (dozens a second) until it is closed."""

    def __init__(self, interval: float = 10.0) -> None:
        super().__init__()
        self._interval = interval
        self._last: dict[str, float] = {}

    def filter(self, record: logging.LogRecord) -> bool:
        text, now = record.getMessage(), time.monotonic()
        if now - self._last.get(text, -self._interval) < self._interval:
            return False
        if len(self._last) > 64:
            self._last.clear()
        self._last[text] = now
        return True


def _quiet_sdk_repeats() -> None:
    sdk = logging.getLogger("foxglove.log_sink_set")
    if not any(isinstance(f, _Repeats) for f in sdk.filters):
        sdk.addFilter(_Repeats())


def recording_names(first: Path) -> Iterator[Path]:
    """The names tried, in order, for a recording asked for as ``first`` (``a.mcap``,
    ``a.1.mcap``, ``a.2.mcap``, ...); it takes the first that does not exist."""
    yield first
    for n in itertools.count(1):
        yield first.with_name(f"{first.stem}.{n}{first.suffix}")


def free_name(first: Path) -> Path:
    """The name a recording asked for as ``first`` gets now (for a reader that must know it)."""
    return next(p for p in recording_names(first) if not p.exists())


def _lock(path: Path, wait: bool = True) -> int:
    """A descriptor holding an exclusive ``flock`` on ``path`` (released when it is closed,
    or when the process dies however it dies); ``wait`` False: BlockingIOError if it is held."""
    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise
    return fd


def _locked(path: Path) -> bool:
    """Whether a running process holds ``path``'s lock (is writing it)."""
    try:
        os.close(_lock(path, wait=False))  # a writer's own lock waits out this probe
    except BlockingIOError:
        return True
    except OSError:
        return False
    return False


def _attach(writer: Any, name: str, data: bytes, media_type: str) -> None:
    now = time.time_ns()
    writer.attach(log_time=now, create_time=now, name=name, media_type=media_type, data=data)


def _close_quietly(writer: Any) -> None:
    """Close a writer whose file is given up; it detaches from the context even if it fails."""
    if writer is not None:
        with contextlib.suppress(Exception):
            writer.close()


_PROBE_BYTES = 64 * 1024


def _disk_problem(directory: Path) -> str | None:
    """Why ``directory`` does not take data now (``No space left on device``), or None: a
    probe file is written, synced and removed."""
    probe = directory / f".percept-probe-{os.getpid()}"
    try:
        with open(probe, "wb") as fh:
            fh.write(bytes(_PROBE_BYTES))
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as err:
        return err.strerror or str(err)
    finally:
        with contextlib.suppress(OSError):
            probe.unlink()
    return None


def _words(err: BaseException) -> str:
    return str(err) or type(err).__name__


def _quaternion(R: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix, by Shepperd's method: from the largest of the four
    components, so nothing is divided by a small number. (Not scipy's Rotation: importing
    scipy.spatial costs the daemon about 40 MB of memory.)"""
    m = np.asarray(R, dtype=float)
    four = [  # 4 w^2, 4 x^2, 4 y^2, 4 z^2
        1 + m[0, 0] + m[1, 1] + m[2, 2],
        1 + m[0, 0] - m[1, 1] - m[2, 2],
        1 - m[0, 0] + m[1, 1] - m[2, 2],
        1 - m[0, 0] - m[1, 1] + m[2, 2],
    ]
    k = int(np.argmax(four))
    s = 2.0 * float(np.sqrt(four[k]))  # four times that component
    wx, wy, wz = m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]  # 4 wx, 4 wy, 4 wz
    xy, xz, yz = m[0, 1] + m[1, 0], m[0, 2] + m[2, 0], m[1, 2] + m[2, 1]  # 4 xy, 4 xz, 4 yz
    w, x, y, z = (
        (s / 4, wx / s, wy / s, wz / s),
        (wx / s, s / 4, xy / s, xz / s),
        (wy / s, xy / s, s / 4, yz / s),
        (wz / s, xz / s, yz / s, s / 4),
    )[k]
    norm = float(np.sqrt(w * w + x * x + y * y + z * z))
    return x / norm, y / norm, z / norm, w / norm


def _scene_update(world: World, ns: int) -> Any:
    """Objects as cylinders in their colour (diameter = width), boxes as cubes, peers as arrows."""
    from foxglove.messages import (
        ArrowPrimitive,
        Color,
        CubePrimitive,
        CylinderPrimitive,
        Duration,
        Pose,
        Quaternion,
        SceneEntity,
        SceneUpdate,
        Timestamp,
        Vector3,
    )

    stamp = Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)
    lifetime = Duration(1, 0)

    def pose(x: float, y: float, z: float, theta: float = 0.0) -> Pose:
        return Pose(
            position=Vector3(x=x, y=y, z=z),
            orientation=Quaternion(
                x=0.0, y=0.0, z=float(np.sin(theta / 2)), w=float(np.cos(theta / 2))
            ),
        )

    cylinders = []
    for obj in world.objects:
        f = obj.features
        x, y = f.get("x"), f.get("y")
        if x is None or y is None:
            continue
        width = max(float(f.get("width") or 0.02), 0.01)
        height = max(float(f.get("height") or 0.02), 0.01)
        r, g, b = ycrcb_to_rgb(f.get("luminance"), f.get("green_red"), f.get("yellow_blue"))
        cylinders.append(
            CylinderPrimitive(
                pose=pose(x, y, height / 2),
                size=Vector3(x=width, y=width, z=height),
                bottom_scale=1.0,
                top_scale=1.0,
                color=Color(r=r, g=g, b=b, a=0.9),
            )
        )
    cubes = [
        CubePrimitive(
            pose=pose(b.x, b.y, 0.1, b.theta),
            size=Vector3(x=0.2, y=0.2, z=0.2),
            color=Color(r=0.75, g=0.6, b=0.4, a=0.6),
        )
        for b in world.boxes
    ]
    arrows = [
        ArrowPrimitive(
            pose=pose(p.x, p.y, 0.05, p.theta),
            shaft_length=0.15,
            shaft_diameter=0.03,
            head_length=0.08,
            head_diameter=0.08,
            color=Color(r=0.0, g=0.0, b=0.0, a=1.0),
        )
        for p in world.peers.values()
    ]
    entity = SceneEntity(
        timestamp=stamp,
        frame_id=GROUND_FRAME,
        id="world",
        lifetime=lifetime,
        cylinders=cylinders,
        cubes=cubes,
        arrows=arrows,
    )
    return SceneUpdate(entities=[entity])


def ycrcb_to_rgb(y: float | None, cr: float | None, cb: float | None) -> tuple[float, float, float]:
    """Mean colour from Y, Cr, Cb means (0..255) as RGB in 0..1; grey when unknown."""
    if y is None or cr is None or cb is None:
        return 0.5, 0.5, 0.5
    import cv2

    pixel = np.array([[[y, cr, cb]]], dtype=np.uint8)
    b, g, r = cv2.cvtColor(pixel, cv2.COLOR_YCrCb2BGR)[0, 0]
    return r / 255.0, g / 255.0, b / 255.0


# -- reading --------------------------------------------------------------------------------------


class RecordedFrame:
    """One frame as recorded: the pipeline's inputs, and its image, decoded on first use."""

    def __init__(self, inputs: dict[str, Any], decode: Any, data: bytes) -> None:
        self.inputs = inputs
        self._decode = decode
        self._data = data
        self._image: np.ndarray | None = None

    @property
    def image(self) -> np.ndarray:
        """The BGR image."""
        if self._image is None:
            message = self._decode(self._data)
            self.image_format = getattr(message, "format", None) or message.encoding
            self._image = _decode_image(message)
        return self._image

    image_format: str | None = None
    """``jpeg`` (lossy) or ``bgr8`` once :attr:`image` was decoded."""


def _no_damage() -> Damage:
    from percept.runtime.record.mcap_salvage import (
        Damage,  # mcap costs the daemon 3 MB; only readers need it
    )

    return Damage()


@dataclass
class Recording:
    """What :func:`read_recording` found: the metadata, the background model, and what was
    damaged or missing (:class:`~percept.runtime.record.mcap_salvage.Damage`).

    ``truncated`` is true when the file ends early (the writer was killed); everything up to
    the last complete chunk was still read.
    """

    path: Path
    metadata: dict[str, str] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    damage: Damage = field(default_factory=_no_damage)

    @property
    def truncated(self) -> bool:
        return self.damage.truncated


class RecordingError(Exception):
    """A file that is not a readable percept recording."""


def read_recording(
    path: str | Path, recording: Recording | None = None
) -> Iterator[tuple[str, Any]]:
    """Stream a recording in file order: ``("frame", RecordedFrame)`` for each processed frame,
    ``("world", dict)`` for each world model, and ``("boxes" | "status", dict)``.

    Reads as far as the file is intact (:mod:`percept.runtime.record.mcap_salvage`): a file without
    summary or footer (a killed writer) reads up to its last complete chunk, a damaged chunk is
    skipped and counted. ``recording`` (if given) collects the metadata and the attachments as they
    come, and ends up saying what was damaged. Raises :class:`RecordingError` for a file that
    is not MCAP.
    """
    from mcap.records import Attachment, Channel, Message, Metadata, Schema
    from mcap_protobuf.decoder import DecoderFactory

    from percept.runtime.record.mcap_salvage import NotMcapError, read_records

    rec = recording if recording is not None else Recording(Path(path))
    decoders = DecoderFactory()
    schemas: dict[int, Any] = {}
    channels: dict[int, Any] = {}
    images: dict[int, tuple[Any, bytes]] = {}
    inputs: dict[int, dict[str, Any]] = {}
    json_topics = {TOPIC_WORLD: "world", TOPIC_BOXES: "boxes", TOPIC_STATUS: "status"}
    try:
        for record in read_records(path, rec.damage):
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Metadata) and record.name == "percept":
                rec.metadata.update(record.metadata)
            elif isinstance(record, Attachment):
                rec.attachments[record.name] = bytes(record.data)
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None:  # its channel record was in a damaged chunk
                    rec.damage.messages += 1
                    continue
                topic, ns = channel.topic, record.log_time
                message: Any = None
                try:
                    if topic in (TOPIC_IMAGE, TOPIC_RAW):
                        decode = decoders.decoder_for(
                            channel.message_encoding, schemas.get(channel.schema_id)
                        )
                        images[ns] = (decode, bytes(record.data))
                    elif topic == TOPIC_FRAME:
                        inputs[ns] = json.loads(record.data)
                    elif topic in json_topics:
                        message = json.loads(record.data)
                except (ValueError, TypeError):  # a damaged message or schema a CRC missed
                    rec.damage.messages += 1
                    continue
                if message is not None:
                    yield json_topics[topic], message
                if ns in images and ns in inputs:
                    yield "frame", RecordedFrame(inputs.pop(ns), *images.pop(ns))
    except NotMcapError as err:
        raise RecordingError(str(err)) from None
    damage = rec.damage
    if damage.any:
        log.warning(
            "%s is damaged: skipped %d chunks, %d records (%d bytes), %d messages; read the rest",
            path,
            damage.chunks,
            damage.records,
            damage.bytes,
            damage.messages,
        )
    if damage.truncated:
        log.info("%s ends early: read to the last complete chunk", path)


def _decode_image(msg: Any) -> np.ndarray:
    """A decoded CompressedImage or RawImage (bgr8) as a BGR array."""
    import cv2

    if hasattr(msg, "format"):
        image = cv2.imdecode(np.frombuffer(msg.data, np.uint8), cv2.IMREAD_COLOR)
        if image is None:
            raise RecordingError(f"cannot decode a {msg.format} image")
        return image
    if msg.encoding != "bgr8":
        raise RecordingError(f"raw image encoding {msg.encoding!r} is not bgr8")
    rows = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)
    return rows[:, : msg.width * 3].reshape(msg.height, msg.width, 3).copy()
