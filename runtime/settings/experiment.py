"""Experiment files: ``config/experiments/<name>.toml``.

An experiment names the robots taking part (each with its platform profile and its Zenoh
endpoint), the landmark boxes, the networking and the perception parameters shared by all robots.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

from percept.config import find
from percept.config.loader import ConfigError, FieldError, load
from percept.drivers.dynamixel.settings import GazeSettings
from percept.drivers.sim.settings import SimSettings
from percept.perception.features.experience import FeatureSettings
from percept.perception.features.scaling import ScalingSettings
from percept.perception.landmarks.settings import LandmarkSettings
from percept.perception.params import BackgroundParams, PerceptionParams
from percept.runtime.daemon.settings import DaemonSettings
from percept.runtime.net.settings import (
    NetworkSettings,
    PeerSettings,
    endpoint_problem,
    name_problem,
    prefix_problem,
)
from percept.runtime.ros2.settings import Ros2Settings
from percept.runtime.settings.profile import PlatformProfile


@dataclass(frozen=True)
class RobotEntry:
    """One robot taking part: its name (used in every key expression), profile and endpoint."""

    name: str = field(metadata={"doc": "robot name, letters, digits, - and _"})
    profile: Path = field(metadata={"doc": "platform profile, relative to this file"})
    endpoint: str = field(
        default="tcp/127.0.0.1:7447", metadata={"doc": "Zenoh endpoint this robot listens on"}
    )

    def __post_init__(self) -> None:
        problem = name_problem(self.name)
        if problem:
            raise ValueError(f"robot name {problem} (messages carry it)")
        problem = endpoint_problem(self.endpoint)
        if problem:
            raise FieldError("endpoint", problem)


@dataclass(frozen=True)
class Experiment:
    """One experiment: who takes part and with which shared parameters."""

    name: str = field(metadata={"doc": "experiment name"})
    robots: tuple[RobotEntry, ...] = field(metadata={"doc": "robots taking part"})
    prefix: str = field(default="percept", metadata={"doc": "first part of every Zenoh key"})
    scaling: ScalingSettings = field(
        default_factory=ScalingSettings, metadata={"doc": "feature statistics for scaling"}
    )
    features: FeatureSettings = field(
        default_factory=FeatureSettings, metadata={"doc": "how sensory experiences are computed"}
    )
    daemon: DaemonSettings = field(
        default_factory=DaemonSettings, metadata={"doc": "rates and bounds of percept run"}
    )
    perception: PerceptionParams = field(
        default_factory=PerceptionParams, metadata={"doc": "perception core thresholds"}
    )
    landmarks: LandmarkSettings = field(
        default_factory=LandmarkSettings, metadata={"doc": "marker detection and landmark boxes"}
    )
    network: NetworkSettings = field(
        default_factory=NetworkSettings, metadata={"doc": "how the processes meet on Zenoh"}
    )
    sim: SimSettings = field(
        default_factory=SimSettings, metadata={"doc": "runs against the simulated world"}
    )
    peers: PeerSettings = field(
        default_factory=PeerSettings, metadata={"doc": "box exchange, peer poses, pointing"}
    )
    gaze: GazeSettings = field(
        default_factory=GazeSettings,
        metadata={"doc": "moving the head (servo writes); off unless enabled"},
    )
    ros2: Ros2Settings = field(
        default_factory=Ros2Settings,
        metadata={"doc": "the world on ROS 2 topics (rmw_zenoh), publish-only; off unless enabled"},
    )

    def __post_init__(self) -> None:
        names = [r.name for r in self.robots]
        if len(set(names)) != len(names):
            raise ValueError(f"robot names must be unique, got {names}")
        problem = prefix_problem(self.prefix)
        if problem:
            raise FieldError("prefix", problem)
        if self.ros2.enabled and self.ros2.router in {r.endpoint for r in self.robots}:
            # rmw_zenohd and a robot both listen on port 7447 unless told otherwise.
            raise FieldError(
                "ros2.router",
                f"{self.ros2.router} is a robot's endpoint too: the ROS 2 router (rmw_zenohd) "
                "needs a port of its own (give the robot or the router another one)",
            )
        for i, player in enumerate(self.peers.players):
            if player not in names:
                raise FieldError(
                    f"peers.players[{i}]", f"{player!r} is not a robot of the experiment: {names}"
                )

    @property
    def players(self) -> tuple[str, ...]:
        """The robots pointing games are played with: ``[peers] players``, else every robot."""
        return self.peers.players or tuple(r.name for r in self.robots)

    def robot(self, name: str) -> RobotEntry:
        """The entry of robot ``name``."""
        for r in self.robots:
            if r.name == name:
                return r
        raise KeyError(name)


def check_gaze(
    path: str | Path, experiment: Experiment, profile: PlatformProfile, sim: bool = False
) -> None:
    """With gaze enabled, the experiment's ``[gaze]`` joints must be servos of ``profile``
    (experiments are shared by robots of different platforms, so this is checked when a robot's
    daemon starts), and a simulation with gaze needs the emulated servos; raises
    :class:`~percept.config.loader.ConfigError` naming the experiment file."""
    gaze = experiment.gaze
    if not gaze.enabled:
        return  # nothing will be written
    if sim and experiment.sim.joints == "direct":
        raise ConfigError(
            path, "sim.joints", 'gaze moves the head through servos: it needs "emulator"'
        )
    servos = [j.name for j in profile.joints]
    unknown = [name for name in gaze.joints if name not in servos]
    if unknown:
        raise ConfigError(
            path,
            "gaze.joints",
            f"{', '.join(unknown)}: not a servo of profile {profile.name!r} "
            f"(its servos: {', '.join(servos) or 'none'})",
        )
    if profile.bus.protocol == 2.0 and gaze.watchdog < 3.0 / profile.bus.rate:
        raise ConfigError(
            path,
            "gaze.watchdog",
            f"{gaze.watchdog:g} s is shorter than three reads of profile {profile.name!r} "
            f"({3.0 / profile.bus.rate:g} s at bus.rate {profile.bus.rate:g})",
        )


def load_experiment(path: str | Path) -> Experiment:
    """Read and validate an experiment file (a path or a shipped name); raises
    :class:`percept.config.loader.ConfigError`."""
    return load(Experiment, find("experiments", path))


def on_network(
    experiment: Experiment,
    prefix: str | None = None,
    endpoints: Mapping[str, str] | None = None,
) -> Experiment:
    """``experiment`` with the key prefix ``prefix`` and the robots' endpoints of ``endpoints``
    (by robot name) instead of its own (``percept run --prefix/--endpoint``): two runs of one
    experiment on one machine, such as two demos, then never hear each other."""
    endpoints = endpoints or {}
    known = [r.name for r in experiment.robots]
    for robot, endpoint in endpoints.items():
        if robot not in known:
            raise ConfigError("--endpoint", robot, f"no robot {robot!r}; known: {', '.join(known)}")
        problem = endpoint_problem(endpoint)
        if problem:
            raise ConfigError("--endpoint", robot, problem)
    if prefix is not None and (problem := prefix_problem(prefix)):
        raise ConfigError("--prefix", "", problem)
    robots = tuple(
        replace(r, endpoint=endpoints.get(r.name, r.endpoint)) for r in experiment.robots
    )
    return replace(experiment, prefix=prefix or experiment.prefix, robots=robots)


def check_calibration_memory(
    background: BackgroundParams, width: int, height: int, file: str | Path, key: str
) -> None:
    """Refuse, before anything starts, a background calibration of ``width`` x ``height`` frames
    that would not fit ``background.calibration_memory``; ``key`` is where the table sits."""
    problem = background.memory_problem(width, height)
    if problem is not None:
        raise ConfigError(file, f"{key}.calibration_frames".lstrip("."), problem)
