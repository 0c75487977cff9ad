"""The daemon's settings: the experiment's ``[daemon]`` table, and what ``percept run`` was asked
to do."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class DaemonSettings:
    """The experiment's ``[daemon]`` table: rates and bounds of the onboard daemon."""

    world_rate: float = field(
        default=0.0,
        metadata={
            "min": 0.0,
            "max": 1000.0,
            "doc": "world models per second on Zenoh; 0: every frame",
        },
    )
    joint_max_age: float = field(
        default=0.05,
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "seconds: a frame whose joint readings are older is marked (pose_fresh false)",
        },
    )
    status_interval: float = field(
        default=1.0, metadata={"min": 0.1, "max": 60.0, "doc": "seconds between status messages"}
    )
    frame_timeout: float = field(
        default=0.5,
        metadata={
            "min": 0.05,
            "max": 86400.0,
            "doc": "seconds without a frame before it is reported as a fault",
        },
    )
    inbox: int = field(
        default=64,
        metadata={"min": 1, "max": 100000, "doc": "bound of each queue of received messages"},
    )
    flood_rate: float = field(
        default=100.0,
        metadata={
            "min": 1.0,
            "max": 1e6,
            "doc": "messages per second on one topic, from other processes together, above "
            "which it is reported as a flood",
        },
    )


@dataclass(frozen=True)
class DaemonOptions:
    """What ``percept run`` was asked to do."""

    robot: str
    profile_path: Path
    experiment_path: Path
    sim_scene: str | None = None
    record: Path | None = None
    raw_images: bool = False
    view_port: int | None = None
    background: Path | None = None
    sim_epoch: float | None = None
    enable_gaze: bool = False
    """Move the head even though the experiment's ``[gaze] enabled`` is false."""
    prefix: str | None = None
    """The key prefix instead of the experiment's (``--prefix``)."""
    endpoints: dict[str, str] = field(default_factory=dict)
    """Robots' endpoints instead of the experiment's, by robot name (``--endpoint``)."""
