"""Robot platform profiles: ``config/robots/<platform>.toml``.

A profile is everything that differs between robots: the servo bus and its joints, the camera and
its lens, and the kinematic chain. Porting percept to a new robot means writing one of these.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from percept.config import find
from percept.config.loader import FieldError, load
from percept.drivers.camera.settings import CameraSettings
from percept.drivers.dynamixel.models import find_model
from percept.drivers.dynamixel.settings import BusSettings, JointSettings
from percept.kinematics.settings import KinematicsSettings
from percept.kinematics.tree import KinematicTree


@dataclass(frozen=True)
class PlatformProfile:
    """One robot platform: servos, camera and kinematics."""

    name: str = field(metadata={"doc": "platform name"})
    kinematics: KinematicsSettings = field(metadata={"doc": "chain from ground to camera"})
    bus: BusSettings = field(default_factory=BusSettings, metadata={"doc": "servo bus"})
    joints: tuple[JointSettings, ...] = field(default=(), metadata={"doc": "servos on the bus"})
    camera: CameraSettings = field(default_factory=CameraSettings, metadata={"doc": "head camera"})
    description: str = field(default="", metadata={"doc": "free text"})

    def __post_init__(self) -> None:
        names = [j.name for j in self.joints]
        ids = [j.id for j in self.joints]
        for what, dupes in (("joint name", _duplicates(names)), ("servo id", _duplicates(ids))):
            if dupes:
                raise ValueError(f"duplicate {what}: {', '.join(dupes)}")
        for i, joint in enumerate(self.joints):
            try:
                find_model(joint.model, self.bus.protocol)
            except ValueError as err:  # a model of the other protocol
                raise FieldError(f"joints[{i}].model", str(err)) from None
        movable = KinematicTree.from_settings(self.kinematics).movable_joints
        for i, name in enumerate(names):
            if name not in movable:
                raise FieldError(
                    f"joints[{i}].name",
                    f"joint {name!r} is not in the kinematic chain; its movable joints: "
                    f"{', '.join(movable) or '(none)'}",
                )

    def joint(self, name: str) -> JointSettings:
        """The servo settings of joint ``name``."""
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(name)


def load_profile(path: str | Path) -> PlatformProfile:
    """Read and validate a platform profile (a path or a shipped name); raises
    :class:`percept.config.loader.ConfigError`.

    A camera ``source`` that is a relative path (a folder or a video file) is relative to the
    profile's folder, like every other path in the file.
    """
    path = find("robots", path)
    profile = load(PlatformProfile, path)
    source = profile.camera.source
    if _is_relative_path(source):
        camera = replace(profile.camera, source=str(path.parent / source))
        profile = replace(profile, camera=camera)
    return profile


def _duplicates(values: Sequence[object]) -> list[str]:
    """The values that occur more than once, as sorted text."""
    return sorted({str(v) for v in values if values.count(v) > 1})


def _is_relative_path(source: str) -> bool:
    """Whether a camera source names a file or folder by a relative path: not a device index,
    ``sim``, a GStreamer pipeline (``!``) or a URL."""
    if source == "sim" or source.isdigit() or "!" in source or "://" in source:
        return False
    return not Path(source).expanduser().is_absolute()
