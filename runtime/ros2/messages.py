"""ROS 2 messages built from a robot's world model, with the standard types of ``rosbags``.

Frames (REP 103 and REP 105): ``<robot>/base_link`` is the robot frame of percept (x forward,
y left, z up, on the ground between the feet); ``<robot>/camera`` is the chapter's camera frame
(x along the optical axis, y left, z up) and ``<robot>/camera_optical`` OpenCV's (x right, y
down, z forward), the frame images are in. ``camera_optical`` hangs below ``camera`` by the one
fixed rotation of :data:`percept.kinematics.camera.CAMERA_FROM_CV` (on ``/tf_static``). Boxes
are ``<robot>/box_<id>`` and a peer ``<robot>/peer_<name>``: a peer's own ``base_link`` would
give that frame two parents once both robots publish.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from percept.kinematics.camera import CAMERA_FROM_CV, CameraModel
from percept.kinematics.pose import quaternion
from percept.runtime.net.messages import World, WorldObject

if TYPE_CHECKING:
    from rosbags.typesys.store import Msg  # the types' protocol; rosbags makes them at run time

#: The type store: ROS 2 Jazzy's standard messages (no vision_msgs: objects are markers).
STORE: Typestore = get_typestore(Stores.ROS2_JAZZY)

#: The ROS 2 type of each topic.
TYPES: dict[str, str] = {
    "tf": "tf2_msgs/msg/TFMessage",
    "tf_static": "tf2_msgs/msg/TFMessage",
    "joint_states": "sensor_msgs/msg/JointState",
    "objects": "visualization_msgs/msg/MarkerArray",
    "camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "camera/camera_info": "sensor_msgs/msg/CameraInfo",
}
#: Topics in the global namespace whatever the node's: tf2 listens on /tf and /tf_static only.
ABSOLUTE = {"tf": "/tf", "tf_static": "/tf_static"}

_T = STORE.types
_Header, _Time = _T["std_msgs/msg/Header"], _T["builtin_interfaces/msg/Time"]
_Duration = _T["builtin_interfaces/msg/Duration"]
_Vector3, _Quaternion = _T["geometry_msgs/msg/Vector3"], _T["geometry_msgs/msg/Quaternion"]
_Point, _Pose = _T["geometry_msgs/msg/Point"], _T["geometry_msgs/msg/Pose"]
_Transform = _T["geometry_msgs/msg/Transform"]
_TransformStamped = _T["geometry_msgs/msg/TransformStamped"]
_TFMessage = _T["tf2_msgs/msg/TFMessage"]
_JointState = _T["sensor_msgs/msg/JointState"]
_CompressedImage, _CameraInfo = (
    _T["sensor_msgs/msg/CompressedImage"],
    _T["sensor_msgs/msg/CameraInfo"],
)
_RegionOfInterest = _T["sensor_msgs/msg/RegionOfInterest"]
_Marker, _MarkerArray = (
    _T["visualization_msgs/msg/Marker"],
    _T["visualization_msgs/msg/MarkerArray"],
)
_ColorRGBA, _MeshFile = _T["std_msgs/msg/ColorRGBA"], _T["visualization_msgs/msg/MeshFile"]
#: visualization_msgs/msg/Marker's constants (ADD, CYLINDER, DELETEALL...) by name.
MARKER: dict[str, int] = {
    name: int(value) for name, _, value in STORE.fielddefs["visualization_msgs/msg/Marker"][0]
}

_OBJECT_COLOUR = (0.1, 0.6, 1.0, 0.8)
_LABEL_HEIGHT = 0.03  # metres: text size of an object's label, drawn this far above it


def type_hash(ros_type: str) -> str:
    """The RIHS01 hash of a standard type, as ROS 2 Jazzy computes it."""
    return STORE.hash_rihs01(ros_type)


def serialize(message: object, ros_type: str) -> bytes:
    """A message in CDR (little endian, with its encapsulation header), as rmw_zenoh sends it."""
    return bytes(STORE.serialize_cdr(message, ros_type))


def deserialize(data: bytes, ros_type: str) -> object:
    """A CDR message back (for readers and tests)."""
    return STORE.deserialize_cdr(data, ros_type)


@dataclass(frozen=True)
class Frames:
    """The tf frame names of one robot (``prefix``: the namespace without its leading /)."""

    prefix: str

    @classmethod
    def of(cls, namespace: str) -> Frames:
        return cls(namespace.strip("/"))

    def name(self, frame: str) -> str:
        return f"{self.prefix}/{frame}" if self.prefix else frame

    @property
    def base(self) -> str:
        return self.name("base_link")

    @property
    def camera(self) -> str:
        return self.name("camera")

    @property
    def optical(self) -> str:
        return self.name("camera_optical")

    def box(self, box_id: int) -> str:
        return self.name(f"box_{box_id}")

    def peer(self, robot: str) -> str:
        return self.name(f"peer_{robot}")


def header(stamp: float, frame_id: str) -> Msg:
    """A header at wall-clock ``stamp`` (seconds since the epoch)."""
    sec = math.floor(stamp)
    nanosec = min(round((stamp - sec) * 1e9), 999_999_999)
    return _Header(stamp=_Time(sec=sec, nanosec=nanosec), frame_id=frame_id)


def _transform(stamp: float, parent: str, child: str, t: Sequence[float], R: np.ndarray) -> Msg:
    x, y, z, w = quaternion(R)
    return _TransformStamped(
        header=header(stamp, parent),
        child_frame_id=child,
        transform=_Transform(
            translation=_Vector3(x=float(t[0]), y=float(t[1]), z=float(t[2])),
            rotation=_Quaternion(x=x, y=y, z=z, w=w),
        ),
    )


def _yaw(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def tf(world: World, frames: Frames) -> Msg:
    """``/tf``: the camera, the boxes and the peers, each from the robot's ``base_link``."""
    stamp = world.stamp
    camera = world.camera
    transforms: list[Msg] = [
        _transform(stamp, frames.base, frames.camera, camera["t"], np.array(camera["R"]))
    ]
    for box in world.boxes:
        transforms.append(
            _transform(stamp, frames.base, frames.box(box.id), (box.x, box.y, 0.0), _yaw(box.theta))
        )
    for robot, peer in sorted(world.peers.items()):
        transforms.append(
            _transform(
                stamp, frames.base, frames.peer(robot), (peer.x, peer.y, 0.0), _yaw(peer.theta)
            )
        )
    return _TFMessage(transforms=transforms)


def tf_static(stamp: float, frames: Frames) -> Msg:
    """``/tf_static``: the optical frame below the camera frame (the one fixed conversion)."""
    return _TFMessage(
        transforms=[
            _transform(stamp, frames.camera, frames.optical, (0.0, 0.0, 0.0), CAMERA_FROM_CV)
        ]
    )


def joint_state(stamp: float, joints: Mapping[str, float]) -> Msg:
    """``joint_states``: the joint angles (radians) the frame's camera pose came from."""
    names = sorted(joints)
    return _JointState(
        header=header(stamp, ""),
        name=names,
        position=np.array([joints[n] for n in names], dtype=np.float64),
        velocity=np.zeros(0),
        effort=np.zeros(0),
    )


def label(obj: WorldObject) -> str:
    """An object's marker text: its anchor id and features as JSON (readable in RViz, and
    exactly what the world model holds)."""
    return json.dumps({"id": obj.id, **obj.features}, sort_keys=True)


def _marker(
    stamp: float,
    frame: str,
    ns: str,
    index: int,
    kind: int,
    pose: Msg,
    scale: Msg,
    text: str,
    action: int = MARKER["ADD"],
) -> Msg:
    return _Marker(
        header=header(stamp, frame),
        ns=ns,
        id=index,
        type=kind,
        action=action,
        pose=pose,
        scale=scale,
        color=_ColorRGBA(*_OBJECT_COLOUR),
        lifetime=_Duration(sec=0, nanosec=0),
        frame_locked=False,
        points=[],
        colors=[],
        texture_resource="",
        texture=_CompressedImage(header=header(0.0, ""), format="", data=np.zeros(0, np.uint8)),
        uv_coordinates=[],
        text=text,
        mesh_resource="",
        mesh_file=_MeshFile(filename="", data=np.zeros(0, np.uint8)),
        mesh_use_embedded_materials=False,
    )


def objects(world: World, frames: Frames) -> Msg:
    """``objects``: each anchor on the ground as a cylinder of its width and height, with a
    label (:func:`label`) above it; a DELETEALL first, so objects gone from the world model go
    from RViz too."""
    stamp = world.stamp
    clear = _pose(0, 0, 0), _scale(0, 0, 0)
    markers: list[Msg] = [
        _marker(stamp, frames.base, "", 0, MARKER["CUBE"], *clear, "", MARKER["DELETEALL"])
    ]
    index = 0
    for obj in world.objects:
        position = obj.position
        if position is None:
            continue
        width = obj.features.get("width") or 0.0
        height = obj.features.get("height") or 0.0
        x, y = position
        markers.append(
            _marker(
                stamp, frames.base, "objects", index, MARKER["CYLINDER"],
                _pose(x, y, height / 2), _scale(width, width, height), "",
            )
        )  # fmt: skip
        markers.append(
            _marker(
                stamp, frames.base, "labels", index, MARKER["TEXT_VIEW_FACING"],
                _pose(x, y, height + _LABEL_HEIGHT), _scale(0, 0, _LABEL_HEIGHT), label(obj),
            )
        )  # fmt: skip
        index += 1
    return _MarkerArray(markers=markers)


def _pose(x: float, y: float, z: float) -> Msg:
    return _Pose(
        position=_Point(x=x, y=y, z=z), orientation=_Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    )


def _scale(x: float, y: float, z: float) -> Msg:
    return _Vector3(x=x, y=y, z=z)


def compressed_image(stamp: float, frames: Frames, image: np.ndarray, quality: int = 80) -> Msg:
    """``camera/image/compressed``: the BGR frame as JPEG, in the optical frame."""
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError("OpenCV could not encode the frame as JPEG")
    return _CompressedImage(header=header(stamp, frames.optical), format="jpeg", data=data.ravel())


def camera_info(stamp: float, frames: Frames, camera: CameraModel) -> Msg:
    """``camera/camera_info``: the intrinsics and lens distortion (OpenCV's model)."""
    K = camera.K
    dist = np.asarray(camera.dist, dtype=np.float64).ravel()
    P = np.zeros((3, 4))
    P[:, :3] = K
    return _CameraInfo(
        header=header(stamp, frames.optical),
        height=camera.height,
        width=camera.width,
        distortion_model="rational_polynomial" if dist.size > 5 else "plumb_bob",
        d=dist if dist.size else np.zeros(5),
        k=np.asarray(K, dtype=np.float64).ravel(),
        r=np.eye(3).ravel(),
        p=P.ravel(),
        binning_x=0,
        binning_y=0,
        roi=_RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )
