"""A robot that turns its head in the simulated world: robot a of ``tabletop-busy``, its head
panning by keyframes, with the scene's objects or only some of them added when asked, at any
image size. Its camera poses come from percept's forward kinematics, with a pan or tilt error
when asked (what joint encoders that are off give)."""

from __future__ import annotations

import dataclasses

import numpy as np

from percept.drivers.sim.scene import Event, JointMotion
from percept.drivers.sim.world import SimWorld
from percept.kinematics.pose import CameraPose
from percept.perception.pipeline import FrameResult, Perception
from percept.runtime.settings.scene import find_scene, load_scene


class PanningRobot:
    """Robot a of ``tabletop-busy``, ``pan`` keyframes ((t, rad), ...) for its head.

    ``objects`` None keeps the scene's objects and timeline; otherwise only the objects named
    there are added, each at ``(t, x, y)``.
    """

    def __init__(
        self,
        pan: tuple[tuple[float, float], ...],
        objects: dict[int, tuple[float, float, float]] | None = None,
        size: tuple[int, int] | None = None,
    ) -> None:
        scene, platforms = load_scene(find_scene("tabletop-busy"))
        robot, *others = scene.robots
        robot = dataclasses.replace(
            robot, joints={**robot.joints, "head_pan": JointMotion(keyframes=pan)}
        )
        scene = dataclasses.replace(scene, robots=(robot, *others))
        if objects is not None:
            scene = dataclasses.replace(
                scene,
                objects=tuple(o for o in scene.objects if o.id in objects),
                timeline=tuple(
                    Event(t=t, action="add", object=i, at=(x, y))
                    for i, (t, x, y) in objects.items()
                ),
            )
        if size is not None:
            platform = platforms[robot.name]
            camera = dataclasses.replace(platform.camera, width=size[0], height=size[1])
            platforms = {**platforms, robot.name: dataclasses.replace(platform, camera=camera)}
        self.name = robot.name
        self.world = SimWorld(scene, platforms)
        self.tree = self.world.robot_model(robot.name).tree
        self.camera = self.world.camera_model(robot.name)

    def close(self) -> None:
        self.world.close()

    def pose(
        self, t: float, pan_error: float = 0.0, tilt_error: float = 0.0, delay: float = 0.0
    ) -> CameraPose:
        """The camera pose at ``t`` from the joint angles read ``delay`` seconds before,
        ``pan_error`` and ``tilt_error`` (radians) added to them."""
        joints = self.world.joint_angles(self.name, t - delay)
        joints["head_pan"] += pan_error
        joints["head_tilt"] += tilt_error
        return self.tree.camera_pose(joints)

    def frames(self, times: np.ndarray) -> list[np.ndarray]:
        return [self.world.render(self.name, float(t)) for t in times]

    def calibrated(
        self, perception: Perception, times: np.ndarray, poses: bool = True, delay: float = 0.0
    ) -> None:
        """``perception`` calibrated on the frames at ``times`` (with their camera poses, from
        joint angles read ``delay`` seconds before)."""
        frames = self.frames(times)
        if poses:
            perception.calibrate(frames, poses=[self.pose(float(t), delay=delay) for t in times])
        else:
            perception.calibrate(frames)

    def run(
        self,
        perception: Perception,
        times: np.ndarray,
        pan_error: float = 0.0,
        tilt_error: float = 0.0,
        delay: float = 0.0,
    ) -> list[FrameResult]:
        """The frames at ``times`` processed with their (erroneous, late) camera poses."""
        out = []
        for t in times.tolist():
            image = self.world.render(self.name, t)
            pose = self.pose(t, pan_error, tilt_error, delay)
            out.append(perception.process(image, t, pose))
        return out
