"""Typed settings of a robot's kinematics and camera lens (``[kinematics]`` and ``[camera.lens]``
tables of a platform profile). Lengths in metres, angles in radians."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

Vec3 = tuple[float, float, float]
JointType = Literal["revolute", "continuous", "prismatic", "fixed"]


@dataclass(frozen=True)
class LensSettings:
    """Camera intrinsics: a calibration file, or the opening angles of an ideal pinhole.

    With opening angles only: ``f_x = (w/2) / tan(phi_h/2)``, ``f_y = (h/2) / tan(phi_v/2)``,
    principal point at the image centre, no distortion.
    """

    intrinsics: Path | None = field(
        default=None, metadata={"doc": "OpenCV YAML or JSON calibration file (camera_matrix, dist)"}
    )
    opening_angles: tuple[float, float] = field(
        default=(1.0123, 0.7854),
        metadata={"min": 0.01, "max": 3.1, "doc": "horizontal and vertical opening angle, radians"},
    )

    def __post_init__(self) -> None:
        # Read the file once so that a missing or damaged calibration is refused when the
        # profile loads (percept config too), with the file and key, not when the camera opens.
        if self.intrinsics is not None:
            from percept.kinematics.camera import load_intrinsics

            load_intrinsics(self.intrinsics)


@dataclass(frozen=True)
class JointSpec:
    """One joint of the tree, URDF style: ``child = parent * T(xyz, rpy) * motion(axis)``."""

    name: str = field(metadata={"doc": "joint name"})
    parent: str = field(metadata={"doc": "parent link"})
    child: str = field(metadata={"doc": "child link"})
    type: JointType = field(default="revolute", metadata={"doc": "URDF joint type"})
    xyz: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata={"min": -1000.0, "max": 1000.0, "doc": "origin offset, metres"},
    )
    rpy: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata={"min": -100.0, "max": 100.0, "doc": "origin roll, pitch, yaw, radians"},
    )
    axis: Vec3 = field(
        default=(0.0, 0.0, 1.0),
        metadata={"min": -1.0, "max": 1.0, "doc": "joint axis in the child frame"},
    )


@dataclass(frozen=True)
class KinematicsSettings:
    """The chain from the robot's ground frame to its camera.

    The tree comes from ``urdf`` or from the inline ``joints`` (or both: inline joints extend the
    URDF and replace its joints of the same name). ``root_link`` is placed in the ground frame
    (SPEC §3: between the feet, x forward, z up) by the fixed ``ground_xyz``/``ground_rpy``
    transform, used where the legs are not modelled; with ``sole_links`` given, the ground frame
    follows the feet instead: its axes are the mean of those links' axes (feet flat on the floor),
    its origin their mean origin moved by ``sole_offset`` (down to the sole, to the foot's middle).
    ``camera_link``'s frame is the chapter's camera frame (x along the optical axis, y left, z up),
    after the fixed ``camera_rpy`` rotation.
    """

    camera_link: str = field(metadata={"doc": "link whose frame is the camera"})
    root_link: str = field(default="base_link", metadata={"doc": "root of the tree"})
    urdf: Path | None = field(default=None, metadata={"doc": "URDF file of the robot"})
    joints: tuple[JointSpec, ...] = field(default=(), metadata={"doc": "inline joints"})
    ground_xyz: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata={
            "min": -1000.0,
            "max": 1000.0,
            "doc": "root link's origin in the ground frame, metres",
        },
    )
    ground_rpy: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata={
            "min": -100.0,
            "max": 100.0,
            "doc": "root link's orientation in the ground frame, radians",
        },
    )
    sole_links: tuple[str, ...] = field(
        default=(), metadata={"doc": "foot links whose midpoint defines the ground frame"}
    )
    sole_offset: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata={
            "min": -1000.0,
            "max": 1000.0,
            "doc": "from the sole links' mean origin to the ground point, in the feet's frame",
        },
    )
    camera_rpy: Vec3 = field(
        default=(0.0, 0.0, 0.0),
        metadata={
            "min": -100.0,
            "max": 100.0,
            "doc": "fixed rotation from camera_link to the camera frame (x optical axis), radians",
        },
    )

    def __post_init__(self) -> None:
        # Build the tree once so that a profile with an unknown link, a cycle or a missing camera
        # link is refused when it is loaded, with the file and key, not when the daemon starts.
        from percept.kinematics.tree import KinematicTree

        if self.urdf is not None and not self.urdf.is_file():
            what = "a folder" if self.urdf.is_dir() else "not found"
            raise ValueError(f"urdf: {self.urdf} is {what}, expected a URDF file")
        KinematicTree.from_settings(self)
