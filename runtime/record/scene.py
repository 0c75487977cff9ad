"""The world model as a Foxglove scene: objects, boxes and peers in the robot's ground frame."""

from __future__ import annotations

import math

from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CubePrimitive,
    CylinderPrimitive,
    Duration,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    Timestamp,
    Vector3,
)

from percept.perception.colour import feature_bgr
from percept.runtime.net.messages import World, WorldObject
from percept.runtime.record.topics import GROUND_FRAME

BOX = Color(r=0.75, g=0.6, b=0.4, a=0.6)  # carton
PEER = Color(r=0.0, g=0.0, b=0.0, a=1.0)


def timestamp(ns: int) -> Timestamp:
    """A log time in nanoseconds as a Foxglove timestamp."""
    return Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)


def scene_update(world: World, ns: int) -> SceneUpdate:
    """Objects as cylinders in their colour (diameter = width; faint when remembered out of
    sight), boxes as cubes, peers as arrows."""
    cubes = [
        CubePrimitive(
            pose=_pose(b.x, b.y, 0.1, b.theta), size=Vector3(x=0.2, y=0.2, z=0.2), color=BOX
        )
        for b in world.boxes
    ]
    arrows = [
        ArrowPrimitive(
            pose=_pose(p.x, p.y, 0.05, p.theta),
            shaft_length=0.15,
            shaft_diameter=0.03,
            head_length=0.08,
            head_diameter=0.08,
            color=PEER,
        )
        for p in world.peers.values()
    ]
    entity = SceneEntity(
        timestamp=timestamp(ns),
        frame_id=GROUND_FRAME,
        id="world",
        lifetime=Duration(1, 0),
        cylinders=[c for c in map(_cylinder, world.objects) if c is not None],
        cubes=cubes,
        arrows=arrows,
    )
    return SceneUpdate(entities=[entity])


def _cylinder(obj: WorldObject) -> CylinderPrimitive | None:
    """An object with a ground position as an upright cylinder of its width, height and colour;
    one remembered out of sight (not visible) faint."""
    f = obj.features
    x, y = f.get("x"), f.get("y")
    if x is None or y is None:
        return None
    width = max(float(f.get("width") or 0.02), 0.01)
    height = max(float(f.get("height") or 0.02), 0.01)
    bgr = feature_bgr(f.get("luminance"), f.get("green_red"), f.get("yellow_blue"))
    b, g, r = (c / 255.0 for c in bgr) if bgr is not None else (0.5, 0.5, 0.5)
    return CylinderPrimitive(
        pose=_pose(x, y, height / 2),
        size=Vector3(x=width, y=width, z=height),
        bottom_scale=1.0,
        top_scale=1.0,
        color=Color(r=r, g=g, b=b, a=0.9 if obj.visible else 0.3),
    )


def _pose(x: float, y: float, z: float, theta: float = 0.0) -> Pose:
    """A pose at (x, y, z) turned by ``theta`` about the vertical."""
    return Pose(
        position=Vector3(x=x, y=y, z=z),
        orientation=Quaternion(x=0.0, y=0.0, z=math.sin(theta / 2), w=math.cos(theta / 2)),
    )
