"""The daemon's settings: the experiment's ``[daemon]`` table, what ``percept run`` was asked
to do, and the profile and experiment as a run uses them, checked before anything opens."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from percept.perception.segmentation.background import BackgroundParams
    from percept.runtime.settings.experiment import Experiment
    from percept.runtime.settings.profile import PlatformProfile


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


def load_run(options: DaemonOptions) -> tuple[PlatformProfile, Experiment]:
    """The robot's profile and the experiment as the run ``options`` use them (its network and
    gaze as the options say), checked against each other: a ``--background`` file, the memory a
    calibration needs, the head's limits for gaze and its calibration sweep (ConfigError naming
    file and key)."""
    from percept.runtime.daemon.gaze import check_sweep
    from percept.runtime.settings.experiment import (
        check_calibration_memory,
        check_gaze,
        load_experiment,
        on_network,
    )
    from percept.runtime.settings.profile import load_profile

    profile = load_profile(options.profile_path)
    experiment = on_network(
        load_experiment(options.experiment_path), options.prefix, options.endpoints
    )
    if options.enable_gaze:  # a person says so: the [gaze] table as it is, enabled
        gaze = dataclasses.replace(experiment.gaze, enabled=True)
        experiment = dataclasses.replace(experiment, gaze=gaze)
    experiment.robot(options.robot)  # the robot is in the experiment (ConfigError)
    background = experiment.perception.background
    saved = None if options.background is None else Path(options.background)
    calibrates = saved is None or not saved.exists()
    if saved is not None and not calibrates:
        _check_background(saved, background)
    else:
        camera = profile.camera
        check_calibration_memory(
            background,
            camera.width,
            camera.height,
            options.experiment_path,
            "perception.background",
        )
    check_gaze(options.experiment_path, experiment, profile, sim=options.sim_scene is not None)
    if calibrates and experiment.gaze.enabled:  # the head sweeps meanwhile
        check_sweep(options.experiment_path, experiment.gaze, profile.joints)
    return profile, experiment


def _check_background(path: Path, params: BackgroundParams) -> None:
    """A ``--background`` file that exists must be a model saved by percept (ConfigError)."""
    from percept.config.loader import ConfigError
    from percept.perception.segmentation.background import BackgroundModel, CalibrationError

    try:
        BackgroundModel.load(path, params)
    except CalibrationError as err:
        raise ConfigError("--background", "", str(err)) from None
