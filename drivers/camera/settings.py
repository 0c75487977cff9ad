"""Typed settings of a camera (the ``[camera]`` table of a platform profile)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from percept.drivers.backoff import check_backoff
from percept.kinematics.settings import LensSettings


@dataclass(frozen=True)
class CameraSettings:
    """Where frames come from and how fast.

    ``source`` is a device index (``"0"``), a V4L2 path (``/dev/video0``), a GStreamer pipeline
    (contains ``!``), a video file, an image folder, or ``"sim"`` for the simulated world.
    """

    source: str = field(
        default="0", metadata={"doc": "device index or path, pipeline, file, folder or sim"}
    )
    width: int = field(default=640, metadata={"min": 16, "max": 8192, "doc": "pixels"})
    height: int = field(default=480, metadata={"min": 16, "max": 8192, "doc": "pixels"})
    fps: float = field(
        default=30.0, metadata={"min": 0.1, "max": 1000.0, "doc": "frames per second"}
    )
    max_age: float = field(
        default=0.1,
        metadata={"min": 0.0, "max": 86400.0, "doc": "seconds: never hand out an older frame"},
    )
    reconnect_backoff: tuple[float, float] = field(
        default=(0.1, 2.0),
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "first and largest wait in seconds between reconnect attempts",
        },
    )
    max_failures: int = field(
        default=5,
        metadata={"min": 1, "max": 1000, "doc": "failed reads in a row before reconnecting"},
    )
    pace: Literal["realtime", "lockstep"] = field(
        default="realtime",
        metadata={
            "doc": "files, folders, simulation: realtime at fps, or lockstep (each frame read "
            "when the consumer asks: every frame once, deterministic replays); devices pace "
            "themselves"
        },
    )
    loop: bool = field(default=False, metadata={"doc": "files and folders: start again at the end"})
    pixel_format: Literal["bgr", "yuyv"] = field(
        default="bgr",
        metadata={
            "doc": "devices: bgr (OpenCV converts every frame to BGR), or yuyv: the camera's raw "
            "YUYV taken straight to YCrCb at perception's grid, BGR made only for the frames "
            "that need it (marker search, recording, viewers)"
        },
    )
    epoch: float = field(
        default=0.0,
        metadata={
            "min": 0.0,
            "max": 4102444800.0,  # 2100-01-01
            "doc": "image folders at realtime pace: wall-clock time (Unix seconds) of the first "
            "image; image i is then read and stamped at epoch + i / fps, late ones skipped, in "
            "step with other recorded streams (percept emulate-servos --epoch); 0: from opening",
        },
    )
    lens: LensSettings = field(default_factory=LensSettings, metadata={"doc": "intrinsics"})
    joint_delay: float = field(
        default=0.0,
        metadata={
            "min": -1.0,
            "max": 1.0,
            "doc": "seconds the joint readings lag the frames: a frame stamped t is posed with "
            "the readings at t + joint_delay (percept calibrate-head measures it)",
        },
    )

    def __post_init__(self) -> None:
        check_backoff(self.reconnect_backoff)
        if self.pixel_format == "yuyv" and not is_device(self.source):
            raise ValueError(
                f'pixel_format: "yuyv" is for a camera device (an index or /dev/...), '
                f"not {self.source!r}"
            )
        if self.pixel_format == "yuyv" and self.width % 2:
            raise ValueError(f"pixel_format: YUYV needs an even width, got {self.width}")


def is_device(source: str) -> bool:
    """Whether ``source`` names a camera device: an index (``"0"``) or a ``/dev/...`` path."""
    return source.isdigit() or source.startswith("/dev/")
