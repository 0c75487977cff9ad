"""The kinematic tree of a robot, from a URDF file and/or inline joints, and forward kinematics.

The tree is checked when it is built: every joint's parent must be reachable from the root link,
each link has at most one parent joint, there are no cycles, and the camera and sole links exist.
Forward kinematics is plain numpy: the chain from the ground frame to the camera is compiled once
(consecutive fixed transforms are multiplied out), so a camera pose costs one small matrix product
per movable joint.
"""

from __future__ import annotations

import logging
import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeGuard, get_args

import numpy as np

from percept.kinematics.pose import CameraPose, invert, transform
from percept.kinematics.settings import JointSpec, JointType, KinematicsSettings

log = logging.getLogger("percept.kinematics")

_TYPES: tuple[str, ...] = get_args(JointType)


def _is_joint_type(kind: str) -> TypeGuard[JointType]:
    return kind in _TYPES


class KinematicsError(ValueError):
    """A kinematic description that cannot be used; the message names the joint or link."""


def _floats(text: str | None, default: tuple[float, float, float], what: str) -> tuple:
    if text is None:
        return default
    parts = text.split()
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3:
        raise KinematicsError(f"{what}: expected three numbers, got {text!r}")
    return values


def read_urdf(path: str | Path) -> tuple[list[JointSpec], set[str]]:
    """The joints (in file order) and link names of a URDF file; no ROS needed.

    URDF defaults apply: a missing ``<origin>`` is the identity, a missing ``<axis>`` is
    ``(1, 0, 0)``. Floating and planar joints cannot be read from encoders and are refused.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise KinematicsError(f"{path}: URDF file not found") from None
    except OSError as err:  # a folder, no permission
        raise KinematicsError(f"{path}: cannot read the URDF file: {err.strerror}") from None
    except ET.ParseError as err:
        raise KinematicsError(f"{path}: not valid XML: {err}") from None
    links = {el.get("name", "") for el in root.findall("link")}
    joints: list[JointSpec] = []
    for el in root.findall("joint"):
        name = el.get("name", "")
        kind = el.get("type", "")
        where = f"{path}: joint {name!r}"
        if not _is_joint_type(kind):
            raise KinematicsError(f"{where}: type {kind!r} is not supported ({', '.join(_TYPES)})")
        parent, child = el.find("parent"), el.find("child")
        if parent is None or child is None:
            raise KinematicsError(f"{where}: needs <parent> and <child>")
        origin, axis = el.find("origin"), el.find("axis")
        joints.append(
            JointSpec(
                name=name,
                parent=parent.get("link", ""),
                child=child.get("link", ""),
                type=kind,
                xyz=_floats(None if origin is None else origin.get("xyz"), (0, 0, 0), where),
                rpy=_floats(None if origin is None else origin.get("rpy"), (0, 0, 0), where),
                axis=_floats(None if axis is None else axis.get("xyz"), (1, 0, 0), where),
            )
        )
        for link in (joints[-1].parent, joints[-1].child):
            if link not in links:
                raise KinematicsError(f"{where}: link {link!r} is not declared in the file")
    return joints, links


@dataclass(frozen=True)
class _Step:
    """One movable joint of a compiled chain: ``T <- T @ origin @ motion(q)``."""

    origin: np.ndarray
    joint: str
    prismatic: bool
    A: np.ndarray  # revolute: skew(axis); prismatic: translation along axis
    B: np.ndarray  # revolute: skew(axis)^2


class _Chain:
    """The transform root <- link as a function of the joint angles, compiled."""

    def __init__(self, path: Sequence[JointSpec], head: np.ndarray, tail: np.ndarray) -> None:
        steps: list[_Step] = []
        pending = head.copy()
        for joint in path:
            pending = pending @ transform(joint.xyz, joint.rpy)
            if joint.type == "fixed":
                continue
            a = np.asarray(joint.axis, dtype=float)
            A, B = np.zeros((4, 4)), np.zeros((4, 4))
            if joint.type == "prismatic":
                A[:3, 3] = a
            else:
                K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
                A[:3, :3] = K
                B[:3, :3] = K @ K
            steps.append(_Step(pending, joint.name, joint.type == "prismatic", A, B))
            pending = np.eye(4)
        self.steps = tuple(steps)
        self.tail = pending @ tail
        self.joints = tuple(s.joint for s in steps)

    def __call__(self, angles: Mapping[str, float]) -> np.ndarray:
        eye = np.eye(4)
        T = eye
        for s in self.steps:
            q = float(angles.get(s.joint, 0.0))
            if s.prismatic:
                motion = eye + q * s.A
            else:
                motion = eye + math.sin(q) * s.A + (1.0 - math.cos(q)) * s.B
            T = T @ s.origin @ motion
        return T @ self.tail

    def batch(self, angles: Mapping[str, np.ndarray], n: int) -> np.ndarray:
        """The transforms (n, 4, 4) for ``n`` sets of angles at once (joint -> (n,) array)."""
        eye = np.eye(4)
        T = np.broadcast_to(eye, (n, 4, 4))
        for s in self.steps:
            q = np.asarray(angles.get(s.joint, np.zeros(n)), dtype=float)[:, None, None]
            if s.prismatic:
                motion = eye + q * s.A
            else:
                motion = eye + np.sin(q) * s.A + (1.0 - np.cos(q)) * s.B
            T = T @ s.origin @ motion
        return T @ self.tail


class KinematicTree:
    """A checked kinematic tree with forward kinematics to any link and to the camera.

    Build it with :meth:`from_settings`. Joint angles are passed as a mapping from joint name to
    radians (metres for prismatic joints); joints not given count as 0 unless ``strict``.
    """

    def __init__(self, settings: KinematicsSettings, joints: Sequence[JointSpec]) -> None:
        self.settings = settings
        self.root = settings.root_link
        self._joints = tuple(joints)
        self._parent_joint = {j.child: j for j in self._joints}
        self._chains: dict[str, _Chain] = {}
        self._fixed_ground = transform(settings.ground_xyz, settings.ground_rpy)
        self._camera_rot = transform((0.0, 0.0, 0.0), settings.camera_rpy)
        self._sole_chains = [self._chain(link) for link in settings.sole_links]
        self._sole_joints = tuple(sorted({n for c in self._sole_chains for n in c.joints}))
        self._sole_offset = np.asarray(settings.sole_offset, dtype=float)
        self._ground_cache: tuple[tuple[float, ...], np.ndarray] | None = None
        head = np.eye(4) if settings.sole_links else self._fixed_ground
        self._camera_chain = _Chain(self._path(settings.camera_link), head, self._camera_rot)

    @classmethod
    def from_settings(cls, settings: KinematicsSettings) -> KinematicTree:
        """Read the URDF (if any), add the inline joints and check the tree."""
        return cls(settings, _checked_joints(settings))

    @property
    def joints(self) -> list[JointSpec]:
        """Every joint of the tree, parents before children (breadth first from the root)."""
        return list(self._joints)

    @property
    def movable_joints(self) -> list[str]:
        """Names of the joints that move (revolute, continuous, prismatic), in tree order."""
        return [j.name for j in self._joints if j.type != "fixed"]

    @property
    def camera_joints(self) -> tuple[str, ...]:
        """The movable joints between the ground frame and the camera."""
        return tuple(dict.fromkeys(self._sole_joints + self._camera_chain.joints))

    @property
    def links(self) -> list[str]:
        """Every link: the root, then each joint's child in tree order."""
        return [self.root, *(j.child for j in self._joints)]

    def _path(self, link: str) -> list[JointSpec]:
        path: list[JointSpec] = []
        while link != self.root:
            joint = self._parent_joint.get(link)
            if joint is None:
                raise KinematicsError(f"link {link!r} is not in the tree rooted at {self.root!r}")
            path.append(joint)
            link = joint.parent
        return path[::-1]

    def _chain(self, link: str) -> _Chain:
        chain = self._chains.get(link)
        if chain is None:
            chain = self._chains[link] = _Chain(self._path(link), np.eye(4), np.eye(4))
        return chain

    def _check(self, angles: Mapping[str, float], needed: Sequence[str], strict: bool) -> None:
        if strict:
            missing = [n for n in needed if n not in angles]
            if missing:
                raise KinematicsError(f"no angle given for joint(s) {', '.join(missing)}")

    def ground_from_root(self, angles: Mapping[str, float] | None = None) -> np.ndarray:
        """The 4x4 transform ground <- root link (fixed, or from the feet's pose)."""
        if not self.settings.sole_links:
            return self._fixed_ground.copy()
        angles = angles or {}
        key = tuple(float(angles.get(n, 0.0)) for n in self._sole_joints)
        if self._ground_cache is not None and self._ground_cache[0] == key:
            return self._ground_cache[1].copy()
        feet = np.stack([chain(angles) for chain in self._sole_chains])
        axes = feet[:, :3, :3].mean(axis=0)
        z = axes[:, 2] / np.linalg.norm(axes[:, 2])
        x = axes[:, 0] - (axes[:, 0] @ z) * z
        x /= np.linalg.norm(x)
        root_ground = np.eye(4)
        root_ground[:3, :3] = np.column_stack([x, np.cross(z, x), z])
        origin = feet[:, :3, 3].mean(axis=0)
        root_ground[:3, 3] = origin + root_ground[:3, :3] @ self._sole_offset
        ground = invert(root_ground)
        self._ground_cache = (key, ground)
        return ground.copy()

    def link_transform(self, link: str, angles: Mapping[str, float], strict: bool = False):
        """The 4x4 pose of ``link`` in the ground frame."""
        chain = self._chain(link)
        self._check(angles, self._sole_joints + chain.joints, strict)
        return self.ground_from_root(angles) @ chain(angles)

    def camera_matrices(self, angles: Mapping[str, np.ndarray]) -> np.ndarray:
        """The 4x4 camera poses ground <- camera (n, 4, 4) for ``n`` sets of joint angles at
        once (joint name -> (n,) array; joints not given count as 0), e.g. over a recording."""
        n = len(next(iter(angles.values()))) if angles else 1
        if not self.settings.sole_links:
            return self._camera_chain.batch(angles, n)
        rows = [{k: float(a[i]) for k, a in angles.items()} for i in range(n)]
        return np.stack([self.camera_pose(row).matrix() for row in rows])

    def camera_pose(self, angles: Mapping[str, float], strict: bool = False) -> CameraPose:
        """The camera's pose in the ground frame for these joint angles."""
        self._check(angles, self.camera_joints, strict)
        T = self._camera_chain(angles)
        if self.settings.sole_links:
            T = self.ground_from_root(angles) @ T
        return CameraPose(R=T[:3, :3].copy(), t=T[:3, 3].copy())


def _checked_joints(settings: KinematicsSettings) -> list[JointSpec]:
    """URDF joints with the inline ones merged in, checked, in breadth-first order from the root."""
    merged, declared = _merged_joints(settings)
    parent_joint = _parent_joints(merged)
    root = settings.root_link
    links = declared | {j.parent for j in merged} | {j.child for j in merged}
    if root not in links and (merged or settings.camera_link != root):
        raise KinematicsError(f"root link {root!r} is not a link of the tree")
    inline_names = {j.name for j in settings.joints}
    reachable = _reachable_joints(merged, parent_joint, root, inline_names)
    up = parent_joint.get(root)
    if up is not None and up.name in reachable:
        raise KinematicsError(f"joint {up.name!r} makes the root link {root!r} its own descendant")
    ordered = _breadth_first([j for j in merged if j.name in reachable], root)
    tree_links = {root} | {j.child for j in ordered}
    wanted = [("camera_link", settings.camera_link)]
    wanted += [(f"sole_links[{i}]", s) for i, s in enumerate(settings.sole_links)]
    for key, link in wanted:
        if link not in tree_links:
            raise KinematicsError(f"{key} {link!r} is not a link of the tree rooted at {root!r}")
    return ordered


def _merged_joints(settings: KinematicsSettings) -> tuple[list[JointSpec], set[str]]:
    """The URDF's joints with the inline ones replacing those of the same name and the other
    inline ones after them, and the links the URDF declares."""
    urdf_joints: list[JointSpec] = []
    declared: set[str] = set()
    if settings.urdf is not None:
        urdf_joints, declared = read_urdf(settings.urdf)
    for origin, joints in (("URDF", urdf_joints), ("inline", settings.joints)):
        names = [j.name for j in joints]
        for name in dict.fromkeys(n for n in names if names.count(n) > 1):
            raise KinematicsError(f"joint {name!r} is defined twice in the {origin} joints")
    inline = {j.name: j for j in settings.joints}
    return [inline.pop(j.name, j) for j in urdf_joints] + list(inline.values()), declared


def _parent_joints(joints: list[JointSpec]) -> dict[str, JointSpec]:
    """Each child link's joint, after checking every joint on its own (axis, two links) and
    that no link has two parents."""
    parent_joint: dict[str, JointSpec] = {}
    for j in joints:
        if j.type != "fixed" and not any(j.axis):
            raise KinematicsError(f"joint {j.name!r}: axis must not be zero")
        if j.parent == j.child:
            raise KinematicsError(f"joint {j.name!r} connects link {j.child!r} to itself")
        other = parent_joint.get(j.child)
        if other is not None:
            raise KinematicsError(
                f"link {j.child!r} has two parent joints, {other.name!r} and {j.name!r}: "
                "in a kinematic tree each link has one parent"
            )
        parent_joint[j.child] = j
    return parent_joint


def _reachable_joints(
    joints: list[JointSpec], parent_joint: dict[str, JointSpec], root: str, inline: set[str]
) -> set[str]:
    """Names of the joints below ``root``, found by walking up from each joint. A cycle is an
    error, and so is an unknown parent link above one of the ``inline`` joints (a URDF's
    joints that hang elsewhere are left out)."""
    reachable: set[str] = set()
    reached_links = {root}
    for j in joints:
        path, link = [j], j.parent
        while link not in reached_links:
            up = parent_joint.get(link)
            if up is None:
                break
            if up in path:
                cycle = " -> ".join(s.name for s in reversed(path[path.index(up) :]))
                raise KinematicsError(f"joints {cycle} form a cycle")
            path.append(up)
            link = up.parent
        if link in reached_links:
            reachable.update(s.name for s in path)
            reached_links.update(s.child for s in path)
        elif any(s.name in inline for s in path):
            raise KinematicsError(
                f"joint {path[-1].name!r}: parent link {link!r} is unknown: it is neither the "
                f"root link {root!r} nor the child of another joint"
            )
        else:
            log.debug("joint %s is not below root link %s; left out", j.name, root)
    return reachable


def _breadth_first(joints: list[JointSpec], root: str) -> list[JointSpec]:
    """``joints`` in breadth-first order from ``root``, siblings in their given order."""
    children: dict[str, list[JointSpec]] = {}
    for j in joints:
        children.setdefault(j.parent, []).append(j)
    ordered: list[JointSpec] = []
    frontier = [root]
    while frontier:
        link = frontier.pop(0)
        for j in children.get(link, []):
            ordered.append(j)
            frontier.append(j.child)
    return ordered
