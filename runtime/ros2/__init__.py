"""Publish-only ROS 2 side: the daemon's world on ROS 2 topics in rmw_zenoh's wire format."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from percept.kinematics.camera import CameraModel
    from percept.runtime.ros2.publisher import Ros2Publisher
    from percept.runtime.ros2.settings import Ros2Settings


def open_ros2(
    settings: Ros2Settings, robot: str, camera: CameraModel | None
) -> Ros2Publisher | None:
    """The ROS 2 publisher when ``[ros2]`` is enabled; None when not: then nothing is imported
    (rosbags), no thread started and no Zenoh session opened."""
    if not settings.enabled:
        return None
    from percept.runtime.ros2.publisher import Ros2Publisher

    return Ros2Publisher(settings, robot, camera)
