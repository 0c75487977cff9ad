"""The ROS 2 publisher: a robot's world models on ROS 2 topics, through rmw_zenoh's router.

Publish-only and apart from percept's own messaging: a Zenoh session of its own, in client
mode to the ROS 2 router (``rmw_zenohd``), so the robots' JSON keys and the ROS 2 graph never
mix, and nothing is ever read from ROS 2. The perception thread only hands each world model over
(:meth:`Ros2Publisher.offer`, never waiting: a newer one replaces one not yet sent); the
publisher's own thread opens the session (retrying while the router is away), declares the
graph's liveliness tokens, and serialises and sends.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import zenoh

from percept.kinematics.camera import CameraModel
from percept.runtime.net.mailbox import DropOldest
from percept.runtime.net.messages import World
from percept.runtime.net.zenoh_config import client_settings, config, zenoh_problem
from percept.runtime.ros2 import messages
from percept.runtime.ros2.names import Node, attachment, full_topic, gid, topic_key
from percept.runtime.ros2.settings import Ros2Settings, Topic

log = logging.getLogger("percept.ros2")

NODE_NAME = "percept"
STATIC_EVERY = 1.0  # seconds between /tf_static samples: volatile, so late subscribers get one soon
RETRY = 2.0  # seconds between attempts to reach the ROS 2 router


@dataclass(frozen=True)
class Snapshot:
    """What one frame gives ROS 2: its world model, the joint angles behind its camera pose
    (radians, None when unknown) and its image when one is due (else None)."""

    world: World
    joints: Mapping[str, float] | None
    image: np.ndarray | None


@dataclass(frozen=True)
class Advertised:
    """One declared topic: fully qualified name, ROS type, key expression and liveliness token."""

    topic: Topic
    name: str
    ros_type: str
    key: str
    token: str


def advertised(settings: Ros2Settings, node: Node) -> list[Advertised]:
    """The topics ``settings`` publishes, with their keys and tokens (entity ids from 1)."""
    out = []
    for entity_id, topic in enumerate(settings.topics, start=1):
        ros_type = messages.TYPES[topic]
        name = messages.ABSOLUTE.get(topic) or full_topic(node.namespace, topic)
        type_hash = messages.type_hash(ros_type)
        out.append(
            Advertised(
                topic,
                name,
                ros_type,
                topic_key(node.domain_id, name, ros_type, type_hash),
                node.publisher_token(entity_id, name, ros_type, type_hash),
            )
        )
    return out


class _Channel:
    """A declared topic's Zenoh publisher, liveliness token and sequence numbers."""

    def __init__(self, session: zenoh.Session, topic: Advertised) -> None:
        self.topic = topic
        self.gid = gid(topic.token)
        self.sequence = 0
        self.publisher = session.declare_publisher(topic.key)
        self.token = session.liveliness().declare_token(topic.token)

    def put(self, payload: bytes) -> None:
        self.sequence += 1
        self.publisher.put(payload, attachment=attachment(self.sequence, time.time_ns(), self.gid))

    def close(self) -> None:
        self.token.undeclare()
        self.publisher.undeclare()


class Ros2Publisher:
    """Robot ``robot``'s world models on the ROS 2 topics of ``settings``; ``camera``: the
    intrinsics for ``camera/camera_info`` (None: that topic stays silent)."""

    def __init__(self, settings: Ros2Settings, robot: str, camera: CameraModel | None) -> None:
        self.settings = settings
        self.namespace = settings.namespace_of(robot)
        self.frames = messages.Frames.of(self.namespace)
        self.camera = camera
        self.samples: Counter[str] = Counter()  # sent, by topic
        self.failures: Counter[str] = Counter()  # messages that could not be built or sent
        self.node: Node | None = None  # once the session is open
        self._wants_image = bool(
            {"camera/image/compressed", "camera/camera_info"} & set(settings.topics)
        )
        self._next_image = -math.inf
        self._last_static = -math.inf
        self._inbox: DropOldest[Snapshot | None] = DropOldest(1)
        self._stop = threading.Event()
        self._session: zenoh.Session | None = None
        self._session_lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name="ros2", daemon=True)
        self._thread.start()

    @property
    def dropped(self) -> int:
        """World models replaced by newer ones before they were sent."""
        return self._inbox.dropped

    def offer(
        self,
        world: World,
        joints: Mapping[str, float] | None,
        image: np.ndarray | Callable[[], np.ndarray],
    ) -> None:
        """Hand over a frame's world model (never waits); its image (or how to make it: made
        only when sent) goes along at most ``image_rate`` times a second."""
        now = time.monotonic()
        sent: np.ndarray | None = None
        if self._wants_image and now >= self._next_image:
            self._next_image = now + 1.0 / self.settings.image_rate
            sent = image() if callable(image) else image
        self._inbox.put(Snapshot(world, joints, sent))

    def close(self) -> None:
        """Stop the thread, withdraw the tokens and close the session. Idempotent."""
        self._stop.set()
        self._inbox.put(None)
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)
        # A thread still busy (a loaded machine) must not leave the session open: an open
        # session can keep the process from exiting.
        self._close_session()

    def _close_session(self) -> None:
        with self._session_lock:
            session, self._session = self._session, None
        if session is not None:
            session.close()

    # -- the publisher's thread -------------------------------------------------------------------

    def _run(self) -> None:
        session = self._open()
        if session is None:
            return
        with self._session_lock:
            if self._stop.is_set():  # closed while the session was opening
                session.close()
                return
            self._session = session
        channels: dict[str, _Channel] = {}
        node_token: zenoh.LivelinessToken | None = None
        try:
            zid = str(session.info.zid())
            node = self.node = Node(self.settings.domain_id, zid, self.namespace, NODE_NAME)
            node_token = session.liveliness().declare_token(node.token())
            for topic in advertised(self.settings, node):
                channels[topic.topic] = _Channel(session, topic)
            log.info(
                "ROS 2: node %s/%s on domain %d via %s, topics %s",
                self.namespace.rstrip("/"),
                NODE_NAME,
                self.settings.domain_id,
                self.settings.router,
                ", ".join(c.topic.name for c in channels.values()),
            )
            while not self._stop.is_set():
                snapshot = self._inbox.get()
                if snapshot is None:
                    break
                self._publish(snapshot, channels)
        finally:
            try:
                for channel in channels.values():
                    channel.close()
                if node_token is not None:
                    node_token.undeclare()
            except zenoh.ZError:  # close() closed the session first: the tokens went with it
                pass
            self._close_session()

    def _open(self) -> zenoh.Session | None:
        """A client session to the router, retried every :data:`RETRY` seconds until it opens
        or the publisher stops (None)."""
        settings = client_settings([self.settings.router], connect_timeout=0.0)
        warned = False
        while not self._stop.is_set():
            try:
                return zenoh.open(config(settings))
            except zenoh.ZError as err:
                if not warned:
                    log.warning(
                        "ROS 2: no router at %s (%s); retrying every %.0f s",
                        self.settings.router,
                        zenoh_problem(err),
                        RETRY,
                    )
                    warned = True
            self._stop.wait(RETRY)
        return None

    def _publish(self, snapshot: Snapshot, channels: Mapping[str, _Channel]) -> None:
        world, frames = snapshot.world, self.frames
        now = time.monotonic()
        built: list[tuple[str, Callable[[], object]]] = [
            ("tf", lambda: messages.tf(world, frames)),
            ("objects", lambda: messages.objects(world, frames)),
        ]
        if snapshot.joints is not None:
            joints = snapshot.joints
            built.append(("joint_states", lambda: messages.joint_state(world.stamp, joints)))
        if now - self._last_static >= STATIC_EVERY:
            self._last_static = now
            built.append(("tf_static", lambda: messages.tf_static(world.stamp, frames)))
        if snapshot.image is not None:
            image = snapshot.image
            built.append(
                (
                    "camera/image/compressed",
                    lambda: messages.compressed_image(world.stamp, frames, image),
                )
            )
            if self.camera is not None:
                camera = self.camera
                built.append(
                    (
                        "camera/camera_info",
                        lambda: messages.camera_info(world.stamp, frames, camera),
                    )
                )
        for topic, build in built:
            channel = channels.get(topic)
            if channel is None:
                continue
            try:
                channel.put(messages.serialize(build(), channel.topic.ros_type))
            except (ValueError, TypeError, zenoh.ZError) as err:
                # A world model ROS 2 cannot take is counted and logged, never fatal.
                if self.failures[topic] == 0:
                    log.error("ROS 2: %s not sent: %s", channel.topic.name, err)
                self.failures[topic] += 1
                continue
            self.samples[topic] += 1
