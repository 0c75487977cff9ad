"""The experiment's ``[ros2]`` table: whether and how a daemon shows its world to ROS 2.

Light enough for config loading: no Zenoh, no rosbags here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Literal

from percept.config.extras import installed, missing
from percept.config.loader import FieldError
from percept.runtime.net.settings import endpoint_problem

Topic = Literal[
    "tf", "tf_static", "joint_states", "objects", "camera/image/compressed", "camera/camera_info"
]
#: Every topic the ROS 2 side can publish, as ``[ros2] topics`` names them.
TOPICS: tuple[Topic, ...] = (
    "tf", "tf_static", "joint_states", "objects", "camera/image/compressed", "camera/camera_info"
)  # fmt: skip

_NAMESPACE = re.compile(r"(/[A-Za-z_][A-Za-z0-9_]*)+")


@dataclass(frozen=True)
class Ros2Settings:
    """The experiment's ``[ros2]`` table (off by default).

    rmw_zenoh's router (``rmw_zenohd``) listens on ``tcp/[::]:7447`` by default, and so does a
    percept robot (its experiment endpoint): on one computer one of them must move.
    """

    enabled: bool = field(default=False, metadata={"doc": "publish the world on ROS 2 topics"})
    domain_id: int = field(
        default=0, metadata={"min": 0, "max": 232, "doc": "ROS_DOMAIN_ID of the ROS 2 graph"}
    )
    namespace: str = field(
        default="",
        metadata={"doc": "ROS 2 namespace of the node and its topics (empty: / + robot name)"},
    )
    router: str = field(
        default="tcp/127.0.0.1:7447",
        metadata={"doc": "Zenoh endpoint of the ROS 2 router (rmw_zenohd)"},
    )
    topics: tuple[Topic, ...] = field(default=TOPICS, metadata={"doc": "the topics published"})
    image_rate: float = field(
        default=2.0,
        metadata={
            "min": 0.1,
            "max": 60.0,
            "doc": "compressed images (and camera info) per second at most",
        },
    )

    def __post_init__(self) -> None:
        if self.enabled and not installed("rosbags"):
            raise FieldError("enabled", str(missing("rosbags")))
        if self.namespace and not _NAMESPACE.fullmatch(self.namespace):
            raise FieldError(
                "namespace",
                f"expected a ROS 2 namespace like /robot_a (/ then letters, digits and _, "
                f"not starting with a digit), got {self.namespace!r}",
            )
        problem = endpoint_problem(self.router)
        if problem:
            raise FieldError("router", problem)
        if len(set(self.topics)) != len(self.topics):
            raise FieldError("topics", f"each topic at most once, got {list(self.topics)}")

    def namespace_of(self, robot: str) -> str:
        """The namespace in use: ``namespace``, else ``/`` + the robot's name (a robot name may
        hold ``-``, which ROS 2 names may not: it becomes ``_``)."""
        return self.namespace or "/" + robot.replace("-", "_")
