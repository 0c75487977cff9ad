"""A scene turned into a MuJoCo model (MJCF text plus its texture images).

Each robot is its kinematic tree from its platform profile: one body per link, a hinge (or slide)
per movable joint, the head camera in the camera link with the profile's resolution and
intrinsics. Robot bodies are drawn as simple capsules and boxes (the meshes real robots have are
not needed to be seen, only to be there). Objects are mocap bodies placed kinematically by the
timeline; boxes are static bodies with their markers as thin textured plates.

Rendering is kept cheap: no shadows unless the scene asks, no multisampling, no collisions.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from percept.drivers.camera.settings import CameraSettings
from percept.drivers.dynamixel.settings import JointSettings
from percept.drivers.sim import textures
from percept.drivers.sim.scene import (
    FloorMarker,
    Scene,
    SceneError,
    SimBox,
    SimObject,
    SimRobot,
)
from percept.kinematics.camera import CAMERA_FROM_CV, CameraModel
from percept.kinematics.pose import marker_on_box, rpy_matrix
from percept.kinematics.settings import KinematicsSettings
from percept.kinematics.tree import KinematicsError, KinematicTree

#: Segmentation labels: an object's label is its id; boxes and robots are offset above them.
BOX_LABEL = 1_000_000
ROBOT_LABEL = 2_000_000

#: Geom group of the one object rendered alone to measure its unoccluded outline.
SOLO_GROUP = 5
#: MuJoCo's camera looks along its -z with +y up and +x right: OpenCV's frame with y and z
#: flipped. Maps MuJoCo camera vectors into the chapter's camera frame.
CAMERA_FROM_MJCAM = CAMERA_FROM_CV @ np.diag([1.0, -1.0, -1.0])
_PIXEL_PITCH = 1e-5  # metres; any value works, MuJoCo only needs focal length and sensor to agree
_PLATE = 0.0005  # half thickness of a marker's paper, metres


class RobotPlatform(Protocol):
    """What the simulation needs of a platform profile
    (``percept.runtime.settings.profile.PlatformProfile``)."""

    @property
    def name(self) -> str: ...

    @property
    def kinematics(self) -> KinematicsSettings: ...

    @property
    def camera(self) -> CameraSettings: ...

    @property
    def joints(self) -> tuple[JointSettings, ...]: ...


@dataclass(frozen=True)
class RobotModel:
    """One robot as modelled: its tree, camera and the names MuJoCo knows its parts by."""

    robot: SimRobot
    platform: RobotPlatform
    tree: KinematicTree
    lens: CameraModel
    group: int  # geom group of its body, hidden from its own camera
    camera: str  # MuJoCo camera name
    joints: dict[str, str]  # joint name -> MuJoCo joint name (movable joints only)


@dataclass(frozen=True)
class SimModel:
    """MJCF text, the texture images it names, and what each geom stands for."""

    xml: str
    assets: dict[str, bytes]
    robots: dict[str, RobotModel]
    labels: dict[str, int]  # geom name -> segmentation label

    def compile(self):
        """The compiled ``mujoco.MjModel``."""
        import mujoco

        return mujoco.MjModel.from_xml_string(self.xml, self.assets)


def _f(values: Sequence[float] | np.ndarray) -> str:
    return " ".join(f"{float(v):.9g}" for v in np.ravel(values))


def _quat(R: np.ndarray) -> str:
    """MuJoCo's (w, x, y, z) quaternion of a rotation matrix."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return _f(q)


def _rgba(color: Sequence[int], alpha: float = 1.0) -> str:
    return _f([c / 255 for c in color] + [alpha])


def _checked_robot(
    robot: SimRobot, platform: RobotPlatform, key: str
) -> tuple[KinematicTree, CameraModel]:
    """The robot's kinematic tree and lens from its profile, checked against its scene motion
    (``key`` names the robot in the scene for errors)."""
    try:
        tree = KinematicTree.from_settings(platform.kinematics)
    except KinematicsError as err:
        raise SceneError(f"{key}.profile", str(err)) from None
    cam = platform.camera
    lens = CameraModel.from_lens(cam.lens, cam.width, cam.height)
    if lens.distorted:
        raise SceneError(
            f"{key}.profile",
            "the simulated camera is an ideal pinhole: give the profile's [camera.lens] "
            "opening angles or an intrinsics file without distortion",
        )
    movable = set(tree.movable_joints)
    for name in robot.joints:
        if name not in movable:
            raise SceneError(f"{key}.joints.{name}", "no movable joint of that name")
    for name in robot.perturb.joint_zero:
        if name not in movable:
            raise SceneError(
                f"{key}.perturb.joint_zero.{name}",
                f"no movable joint of that name; the robot's movable joints: "
                f"{', '.join(tree.movable_joints) or '(none)'}",
            )
    servos = {j.name: j for j in platform.joints}
    for name, motion in robot.joints.items():
        lo, hi = motion.bounds()
        servo = servos.get(name)
        if servo is not None and (lo < servo.min - 1e-9 or hi > servo.max + 1e-9):
            raise SceneError(
                f"{key}.joints.{name}",
                f"moves over {lo:.3f} to {hi:.3f} rad, beyond the joint's limits "
                f"{servo.min} to {servo.max}",
            )
    return tree, lens


@dataclass(frozen=True)
class _Look:
    """How one robot's geoms are named, labelled and drawn."""

    robot: str  # robot name, the prefix of its MuJoCo names
    label: int  # segmentation label
    attrs: dict[str, str]  # rgba and geom group


class _Builder:
    """Writes the MJCF document of one scene."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.root = ET.Element("mujoco", model=scene.name)
        ET.SubElement(self.root, "compiler", angle="radian", autolimits="true")
        option = ET.SubElement(self.root, "option")
        ET.SubElement(option, "flag", contact="disable", gravity="disable")
        default = ET.SubElement(self.root, "default")
        ET.SubElement(default, "geom", contype="0", conaffinity="0")
        self.visual = ET.SubElement(self.root, "visual")
        self.asset = ET.SubElement(self.root, "asset")
        self.world = ET.SubElement(self.root, "worldbody")
        self.assets: dict[str, bytes] = {}
        self.labels: dict[str, int] = {}

    def geom(self, parent: ET.Element, name: str, label: int, **attrs: str) -> None:
        ET.SubElement(parent, "geom", {"name": name, **attrs})
        self.labels[name] = label

    def texture(self, name: str, rgb: np.ndarray) -> None:
        self.assets[f"{name}.png"] = textures.png(rgb)
        ET.SubElement(self.asset, "texture", name=name, type="2d", file=f"{name}.png")

    def environment(self, max_size: tuple[int, int]) -> None:
        scene = self.scene
        light = scene.lighting
        ET.SubElement(self.visual, "global", offwidth=str(max_size[0]), offheight=str(max_size[1]))
        ET.SubElement(
            self.visual, "quality", shadowsize=str(light.shadows), offsamples="0", numslices="16"
        )
        ET.SubElement(self.visual, "map", znear="0.004", zfar="40")
        ET.SubElement(
            self.visual, "headlight", ambient=_f(light.ambient), diffuse="0 0 0", specular="0 0 0"
        )
        # extent scales znear/zfar: with 1, the near plane is 4 mm from the lens
        ET.SubElement(self.root, "statistic", extent="1", center="0 0 0.2")
        ET.SubElement(
            self.asset,
            "texture",
            name="sky",
            type="skybox",
            builtin="gradient",
            rgb1="0.72 0.74 0.78",
            rgb2="0.32 0.33 0.36",
            width="64",
            height="64",
        )
        floor = scene.floor
        self.texture("floor", textures.floor_texture(floor.texture, floor.color, scene.seed))
        ET.SubElement(
            self.asset,
            "material",
            name="floor",
            texture="floor",
            texuniform="true",
            texrepeat=_f([1 / floor.tile, 1 / floor.tile]),
            specular="0.05",
            shininess="0.1",
        )
        self.geom(
            self.world,
            "floor",
            0,
            type="plane",
            size=_f([floor.size[0] / 2, floor.size[1] / 2, 0.05]),
            material="floor",
        )
        for i, lamp in enumerate(light.lights):
            ET.SubElement(
                self.world,
                "light",
                name=f"light{i}",
                pos=_f(lamp.position),
                dir=_f(lamp.direction),
                directional=str(lamp.directional).lower(),
                diffuse=_f(lamp.diffuse),
                specular="0.1 0.1 0.1",
                castshadow=str(light.shadows > 0).lower(),
            )

    def obj(self, obj: SimObject) -> None:
        """A mocap body whose frame is the centre of the object's bounding box."""
        body = ET.SubElement(self.world, "body", name=f"obj{obj.id}", mocap="true")
        sx, sy, sz = obj.size
        rgba = _rgba(obj.color)
        look = {"rgba": rgba}
        name = f"obj{obj.id}"
        if obj.shape in ("block", "cuboid"):
            self.geom(
                body, f"{name}/0", obj.id, type="box", size=_f([sx / 2, sy / 2, sz / 2]), **look
            )
        elif obj.shape == "cylinder":
            self.geom(body, f"{name}/0", obj.id, type="cylinder", size=_f([sx / 2, sz / 2]), **look)
        elif obj.shape == "ball":
            self.geom(body, f"{name}/0", obj.id, type="sphere", size=_f([sx / 2]), **look)
        elif obj.shape == "figure":  # a person: a capsule as tall as the figure
            half = (sz - sx) / 2
            self.geom(body, f"{name}/0", obj.id, type="capsule", size=_f([sx / 2, half]), **look)
        elif obj.shape == "cone":
            n = 32
            ring = [
                (sx / 2 * math.cos(a), sx / 2 * math.sin(a), -sz / 2)
                for a in np.linspace(0, 2 * math.pi, n, endpoint=False)
            ]
            ET.SubElement(
                self.asset,
                "mesh",
                name=f"{name}/cone",
                vertex=_f(np.array([(0, 0, sz / 2), *ring])),
            )
            self.geom(body, f"{name}/0", obj.id, type="mesh", mesh=f"{name}/cone", **look)
        else:  # toy: a teddy-like figure, body, head, ears and snout in a darker shade
            head = min(0.3 * sz, 0.4 * min(sx, sy))
            head_z = sz / 2 - head
            trunk = sz - 1.6 * head
            accent = _rgba([int(0.65 * c) for c in obj.color])
            parts = [
                ("ellipsoid", [0, 0, -sz / 2 + trunk / 2], [sx / 2, sy / 2, trunk / 2], rgba),
                ("sphere", [0, 0, head_z], [head], rgba),
                ("sphere", [0, 0.7 * head, head_z + 0.55 * head], [0.4 * head], accent),
                ("sphere", [0, -0.7 * head, head_z + 0.55 * head], [0.4 * head], accent),
                ("sphere", [0.75 * head, 0, head_z - 0.15 * head], [0.35 * head], accent),
            ]
            for k, (kind, pos, size, color) in enumerate(parts):
                self.geom(
                    body, f"{name}/{k}", obj.id, type=kind, pos=_f(pos), size=_f(size), rgba=color
                )

    def box(self, box: SimBox) -> None:
        x, y, yaw = box.pose
        length, width, height = box.size
        body = ET.SubElement(
            self.world,
            "body",
            name=f"box{box.id}",
            pos=_f([x, y, 0]),
            quat=_quat(rpy_matrix((0.0, 0.0, yaw))),
        )
        label = BOX_LABEL + box.id
        self.geom(
            body,
            f"box{box.id}/carton",
            label,
            type="box",
            pos=_f([0, 0, height / 2]),
            size=_f([length / 2, width / 2, height / 2]),
            rgba=_rgba(box.color),
        )
        for m in box.markers:
            name = f"marker{m.id}"
            self.texture(name, textures.marker_texture(self.scene.marker_dictionary, m.id))
            ET.SubElement(self.asset, "material", name=name, texture=name, specular="0.1")
            T = marker_on_box(box.size, m.face, m.offset, m.roll)
            # the plate's +z face shows the texture upright (columns along +x, rows along -y)
            self.geom(
                body,
                f"box{box.id}/{name}",
                label,
                type="box",
                pos=_f(T[:3, 3] + T[:3, 2] * _PLATE),
                quat=_quat(T[:3, :3]),
                size=_f([m.paper / 2, m.paper / 2, _PLATE]),
                material=name,
            )

    def floor_marker(self, marker: FloorMarker) -> None:
        """A marker's sheet lying on the floor, its texture upright along the marker's y."""
        name = f"marker{marker.id}"
        self.texture(name, textures.marker_texture(self.scene.marker_dictionary, marker.id))
        ET.SubElement(self.asset, "material", name=name, texture=name, specular="0.1")
        T = marker.matrix()
        self.geom(
            self.world,
            f"floor/{name}",
            0,  # part of the floor for the segmentation: no object
            type="box",
            pos=_f(T[:3, 3] + T[:3, 2] * _PLATE),
            quat=_quat(T[:3, :3]),
            size=_f([1.5 * marker.side / 2, 1.5 * marker.side / 2, _PLATE]),
            material=name,
        )

    def robot(self, robot: SimRobot, platform: RobotPlatform, index: int) -> RobotModel:
        tree, lens = _checked_robot(robot, platform, f"robots[{index}]")
        group = 1 + index
        look = _Look(
            robot.name, ROBOT_LABEL + index, {"rgba": _rgba(robot.color), "group": str(group)}
        )
        rest = tree.camera_pose(robot.angles(0.0))
        s = max(float(rest.t[2]), 0.1) / 0.48  # body proportions scale with the camera height
        root = self.robot_base(robot, tree, look, s)
        bodies, joints = self.robot_links(tree, root, look, s)
        camera = self.robot_head(
            bodies[tree.settings.camera_link], tree, lens, look, s, robot.perturb.mounting()
        )
        return RobotModel(
            robot=robot,
            platform=platform,
            tree=tree,
            lens=lens,
            group=group,
            camera=camera,
            joints=joints,
        )

    def robot_base(self, robot: SimRobot, tree: KinematicTree, look: _Look, s: float) -> ET.Element:
        """The robot's ground body on the floor, its root link body, legs and torso; returns the
        root link's body."""
        name = robot.name
        x, y, yaw = robot.pose
        ground = ET.SubElement(
            self.world,
            "body",
            name=f"{name}/ground",
            pos=_f([x, y, 0]),
            quat=_quat(rpy_matrix((0.0, 0.0, yaw))),
        )
        G = tree.ground_from_root(robot.angles(0.0))
        root = ET.SubElement(
            ground, "body", name=f"{name}/{tree.root}", pos=_f(G[:3, 3]), quat=_quat(G[:3, :3])
        )
        # legs and torso, drawn in the ground frame's proportions below the root link
        hip = G[:3, 3]
        for side in (-1, 1):
            self.geom(
                ground,
                f"{name}/leg{side:+d}",
                look.label,
                type="capsule",
                fromto=_f([hip[0], side * 0.035 * s, 0.02 * s, hip[0], side * 0.035 * s, hip[2]]),
                size=_f([0.022 * s]),
                **look.attrs,
            )
        self.geom(
            root,
            f"{name}/torso",
            look.label,
            type="box",
            pos=_f([-0.01 * s, 0, 0.03 * s]),
            size=_f([0.045 * s, 0.075 * s, 0.075 * s]),
            **look.attrs,
        )
        return root

    def robot_links(
        self, tree: KinematicTree, root: ET.Element, look: _Look, s: float
    ) -> tuple[dict[str, ET.Element], dict[str, str]]:
        """One body per link below ``root``, a joint per movable joint, a capsule along each
        longer link; returns the bodies by link name and the MuJoCo names of the joints."""
        name = look.robot
        bodies = {tree.root: root}
        joints: dict[str, str] = {}
        for j in tree.joints:
            parent = bodies[j.parent]
            child = ET.SubElement(
                parent,
                "body",
                name=f"{name}/{j.child}",
                pos=_f(j.xyz),
                quat=_quat(rpy_matrix(j.rpy)),
            )
            bodies[j.child] = child
            if j.type != "fixed":
                ET.SubElement(
                    child, "inertial", pos="0 0 0", mass="0.01", diaginertia="1e-6 1e-6 1e-6"
                )
                kind = "slide" if j.type == "prismatic" else "hinge"
                ET.SubElement(child, "joint", name=f"{name}/{j.name}", type=kind, axis=_f(j.axis))
                joints[j.name] = f"{name}/{j.name}"
            if np.linalg.norm(j.xyz) > 0.02 and j.child != tree.settings.camera_link:
                self.geom(
                    parent,
                    f"{name}/{j.name}/link",
                    look.label,
                    type="capsule",
                    fromto=_f([0, 0, 0, *j.xyz]),
                    size=_f([0.012 * s]),
                    **look.attrs,
                )
        return bodies, joints

    def robot_head(
        self,
        camera_body: ET.Element,
        tree: KinematicTree,
        lens: CameraModel,
        look: _Look,
        s: float,
        mounting: np.ndarray,
    ) -> str:
        """The head and the camera in the camera link's body, the camera moved by ``mounting``
        (profile camera <- rendered camera); returns the camera's MuJoCo name."""
        name = look.robot
        turn = rpy_matrix(tree.settings.camera_rpy)
        # the head: a box just behind the lens, so the camera never looks out of its own head
        self.geom(
            camera_body,
            f"{name}/head",
            look.label,
            type="box",
            pos=_f(turn @ np.array([-0.045 * s, 0.0, 0.0])),
            quat=_quat(turn),
            size=_f([0.038 * s, 0.05 * s, 0.042 * s]),
            **look.attrs,
        )
        w, h = lens.width, lens.height
        ET.SubElement(
            camera_body,
            "camera",
            name=f"{name}/camera",
            pos=_f(turn @ mounting[:3, 3]),
            quat=_quat(turn @ mounting[:3, :3] @ CAMERA_FROM_MJCAM),
            resolution=f"{w} {h}",
            sensorsize=_f([w * _PIXEL_PITCH, h * _PIXEL_PITCH]),
            focalpixel=_f([lens.fx, lens.fy]),
            # MuJoCo's principal point is an offset from the image centre, pointing the other way
            principalpixel=_f([(w / 2 - 0.5) - lens.cx, (h / 2 - 0.5) - lens.cy]),
        )
        return f"{name}/camera"


def build_model(scene: Scene, platforms: Mapping[str, RobotPlatform]) -> SimModel:
    """The MuJoCo model of ``scene``; ``platforms`` gives each robot's profile by robot name.

    Raises :class:`SceneError` (with the scene key) for a robot whose profile does not fit.
    """
    missing = [r.name for r in scene.robots if r.name not in platforms]
    if missing:
        raise SceneError("robots", f"no platform profile for robot(s) {', '.join(missing)}")
    b = _Builder(scene)
    largest = (
        max(platforms[r.name].camera.width for r in scene.robots),
        max(platforms[r.name].camera.height for r in scene.robots),
    )
    b.environment(largest)
    robots = {r.name: b.robot(r, platforms[r.name], i) for i, r in enumerate(scene.robots)}
    for obj in scene.objects:
        b.obj(obj)
    for box in scene.boxes:
        b.box(box)
    for marker in scene.floor_markers:
        b.floor_marker(marker)
    ET.indent(b.root)
    xml = ET.tostring(b.root, encoding="unicode")
    return SimModel(xml=xml, assets=b.assets, robots=robots, labels=b.labels)
