"""A corrected copy of a platform profile: the original's text with some keys changed, each
changed line carrying a comment that says what it was and why it changed. The original file is
never written."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from percept.kinematics.calibration import (
    HeadCalibration,
    corrected_mount,
    corrected_origin,
    xyz_rpy,
)
from percept.kinematics.settings import JointSpec
from percept.kinematics.tree import KinematicTree

_JOINTS_HEADER = "[[kinematics.joints]]"
_HEADER = re.compile(r"^\s*\[")


@dataclass(frozen=True)
class JointOrigin:
    """A joint's new origin (metres, URDF roll, pitch, yaw in radians) and why."""

    joint: JointSpec
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    why: str


def _numbers(values: Sequence[float]) -> str:
    return "[" + ", ".join(f"{v:.6f}" for v in values) + "]"


def _set_key(block: list[str], key: str, value: str, why: str, after: int) -> None:
    """Set ``key = value  # why`` in the lines of one table, replacing its line or adding one
    after line ``after``."""
    pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
    for i, line in enumerate(block):
        if pattern.match(line):
            old = line.split("=", 1)[1].split("#", 1)[0].strip()
            block[i] = f"{key} = {value}  # {why} (was {old})"
            return
    block.insert(after + 1, f"{key} = {value}  # {why} (was not set)")


def _tables(lines: list[str]) -> list[tuple[int, int]]:
    """(first, end) line ranges of each table, the header line first."""
    starts = [i for i, line in enumerate(lines) if _HEADER.match(line)]
    return list(zip(starts, [*starts[1:], len(lines)], strict=True))


def corrected_profile(
    text: str, origins: Sequence[JointOrigin], camera: dict[str, tuple[float, str]]
) -> str:
    """The profile ``text`` with each joint of ``origins`` given its new origin (in its inline
    ``[[kinematics.joints]]`` table, or a new one that replaces a URDF joint) and the
    ``[camera]`` keys of ``camera`` (key -> (value, why)) set."""
    lines = text.splitlines()
    for origin in origins:
        joint = origin.joint
        for first, end in _tables(lines):
            if lines[first].strip() != _JOINTS_HEADER:
                continue
            block = lines[first:end]
            if not any(re.match(rf'^\s*name\s*=\s*"{re.escape(joint.name)}"', b) for b in block):
                continue
            name_at = next(i for i, b in enumerate(block) if b.lstrip().startswith("name"))
            for key, new, old in (("xyz", origin.xyz, joint.xyz), ("rpy", origin.rpy, joint.rpy)):
                if max(abs(a - b) for a, b in zip(new, old, strict=True)) > 1e-9:
                    _set_key(block, key, _numbers(new), origin.why, name_at)
            lines[first:end] = block
            break
        else:
            lines += [
                "",
                f"# Replaces the URDF's joint {joint.name!r}: {origin.why}.",
                _JOINTS_HEADER,
                f'name = "{joint.name}"',
                f'parent = "{joint.parent}"',
                f'child = "{joint.child}"',
                f'type = "{joint.type}"',
                f"xyz = {_numbers(origin.xyz)}",
                f"rpy = {_numbers(origin.rpy)}",
                f"axis = {_numbers(joint.axis)}",
            ]
    if camera:
        table = next((r for r in _tables(lines) if lines[r[0]].strip() == "[camera]"), None)
        if table is None:
            lines += ["", "[camera]"]
            table = (len(lines) - 1, len(lines))
        first, end = table
        block = lines[first:end]
        for key, (value, why) in camera.items():
            _set_key(block, key, f"{value:.4f}", why, 0)
        lines[first:end] = block
    return "\n".join(lines) + "\n"


def write_corrected(original: Path, out: Path, text: str) -> None:
    """Write the corrected copy to ``out``, refusing to overwrite ``original``."""
    if out.resolve() == original.resolve():
        raise ValueError(f"{out}: the corrected profile must not replace the original")
    out.write_text(text, encoding="utf-8")


def calibrated_profile(text: str, tree: KinematicTree, result: HeadCalibration) -> str:
    """The profile ``text`` (of the robot whose chain is ``tree``) corrected by a head
    calibration: the camera's joint moved by the mounting, each estimated joint zero turned
    out of its joint's origin, the delay as ``[camera] joint_delay``."""
    specs = {j.name: j for j in tree.joints}
    offset = ", ".join(f"{e.value * 1000:+.1f}" for e in result.camera_offset)
    turn = ", ".join(f"{math.degrees(e.value):+.2f}" for e in result.camera_rotation)
    mount_joint, mount = corrected_mount(tree, result.mounting())
    xyz, rpy = xyz_rpy(mount)
    why = f"calibrate-head: camera moved ({offset}) mm, turned ({turn}) deg on its link"
    if result.folded:
        why += f" (with {', '.join(result.folded)}'s zero)"
    origins = [JointOrigin(specs[mount_joint], xyz, rpy, why)]
    for name, zero in result.joint_zero.items():
        xyz, rpy = xyz_rpy(corrected_origin(tree, name, zero.value))
        why = (
            f"calibrate-head: {name} reads {math.degrees(zero.value):+.2f} deg more than it stands"
        )
        origins.append(JointOrigin(specs[name], xyz, rpy, why))
    late = f"calibrate-head: joint readings {result.delay.value * 1000:+.1f} ms late"
    return corrected_profile(text, origins, {"joint_delay": (result.delay.value, late)})
