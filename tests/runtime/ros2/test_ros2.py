"""The ROS 2 side without ROS: a plain Zenoh session on 127.0.0.1 stands in for rmw_zenohd,
subscribes to the documented key expressions and liveliness tokens, and decodes with rosbags."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import zenoh
from zenoh.ext import Int64, z_deserialize

from percept.config.loader import ConfigError
from percept.kinematics.camera import CAMERA_FROM_CV, CameraModel
from percept.perception.landmarks.records import BoxPose
from percept.runtime.net.messages import PeerPose, World, WorldObject
from percept.runtime.ros2 import messages
from percept.runtime.ros2.names import Node, dds_type, gid, topic_key
from percept.runtime.ros2.publisher import Ros2Publisher, advertised
from percept.runtime.ros2.settings import TOPICS, Ros2Settings
from percept.runtime.settings.experiment import load_experiment
from tests.support.polling import wait_for
from tests.support.zenoh_rig import PROFILE, free_port

CAMERA = CameraModel(
    np.array([[200.0, 0, 87.5], [0, 200.0, 71.5], [0, 0, 1]]), width=176, height=144
)


def rotation(yaw: float, pitch: float) -> np.ndarray:
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    return Rz @ Ry


def world(frame: int = 1) -> World:
    R = rotation(0.3 + 0.01 * frame, 0.6)
    return World(
        robot="robot-a",
        stamp=1_800_000_000.123456 + frame / 30,
        frame=frame,
        camera={"R": R.tolist(), "t": [0.021, -0.013, 0.452]},
        objects=(
            WorldObject(
                id=7,
                bbox=(10.0, 20.0, 30.0, 40.0),
                features={"x": 0.41, "y": -0.12, "width": 0.06, "height": 0.09, "luminance": 0.37},
            ),
            WorldObject(id="b:3", bbox=(1.0, 2.0, 3.0, 4.0), features={"x": 0.5, "y": 0.2}),
            WorldObject(id=9, bbox=(1.0, 2.0, 3.0, 4.0), features={"x": None}, on_ground=False),
        ),
        boxes=(BoxPose(2, 0.8, 0.1, 1.2, 5), BoxPose(5, 0.7, -0.4, -2.0, 1)),
        peers={"robot-b": PeerPose(1.4, 0.2, 3.0, 1_800_000_000.0, 2)},
    )


def settings(port: int, **fields: object) -> Ros2Settings:
    return Ros2Settings(enabled=True, router=f"tcp/127.0.0.1:{port}", **fields)  # type: ignore[arg-type]


@pytest.fixture
def router() -> tuple[zenoh.Session, int]:
    """A plain Zenoh router session on a free local port, as rmw_zenohd would be."""
    port = free_port()
    conf = zenoh.Config.from_json5(
        f'{{mode: "router", listen: {{endpoints: ["tcp/127.0.0.1:{port}"]}},'
        " scouting: {multicast: {enabled: false}}}"
    )
    session = zenoh.open(conf)
    yield session, port
    session.close()


def quaternion_matrix(q: object) -> np.ndarray:
    x, y, z, w = q.x, q.y, q.z, q.w  # type: ignore[attr-defined]
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def check_tf(message: object, w: World) -> None:
    """A /tf message against the world model: poses within 1e-9, frame names exact."""
    by_child = {t.child_frame_id: t for t in message.transforms}  # type: ignore[attr-defined]
    assert set(by_child) == {
        "robot_a/camera", "robot_a/box_2", "robot_a/box_5", "robot_a/peer_robot-b"
    }  # fmt: skip
    camera = by_child["robot_a/camera"]
    assert camera.header.frame_id == "robot_a/base_link"
    assert camera.header.stamp.sec + camera.header.stamp.nanosec * 1e-9 == pytest.approx(
        w.stamp, abs=1e-6
    )
    tr = camera.transform.translation
    np.testing.assert_allclose([tr.x, tr.y, tr.z], w.camera["t"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        quaternion_matrix(camera.transform.rotation), w.camera["R"], rtol=0, atol=1e-9
    )
    for box in w.boxes:
        t = by_child[f"robot_a/box_{box.id}"].transform
        assert (t.translation.x, t.translation.y, t.translation.z) == (box.x, box.y, 0.0)
        yaw = np.arctan2(2 * t.rotation.w * t.rotation.z, 1 - 2 * t.rotation.z**2)
        assert yaw == pytest.approx(box.theta, abs=1e-9)
    peer = by_child["robot_a/peer_robot-b"].transform
    assert (peer.translation.x, peer.translation.y) == (1.4, 0.2)


def check_objects(message: object, w: World) -> None:
    """Markers: a DELETEALL, then a cylinder and a label for each object on the ground."""
    markers = message.markers  # type: ignore[attr-defined]
    assert markers[0].action == 3
    labels = [m for m in markers if m.ns == "labels"]
    cylinders = [m for m in markers if m.ns == "objects"]
    on_ground = [o for o in w.objects if o.position is not None]
    assert len(labels) == len(cylinders) == len(on_ground) == 2
    for obj, text, body in zip(on_ground, labels, cylinders, strict=True):
        decoded = json.loads(text.text)
        assert decoded.pop("id") == obj.id
        assert decoded == obj.features
        assert (body.pose.position.x, body.pose.position.y) == obj.position


def test_type_hashes_are_the_published_ones() -> None:
    """RIHS01 hashes of ROS 2 Jazzy (as `ros2 topic info -v` prints them) for our types."""
    assert messages.type_hash("std_msgs/msg/String") == (
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    )  # the example of rmw_zenoh's design document
    assert messages.type_hash("tf2_msgs/msg/TFMessage") == (
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
    )


def test_key_expressions_and_tokens_follow_rmw_zenoh() -> None:
    node = Node(0, "1f2e3d", "/robot_a", "percept")
    assert node.token() == "@ros2_lv/0/1f2e3d/0/0/NN/%/%robot_a/percept"
    topics = {a.topic: a for a in advertised(Ros2Settings(enabled=True), node)}
    assert set(topics) == set(TOPICS)
    tf = topics["tf"]
    assert tf.key == "0/tf/tf2_msgs::msg::dds_::TFMessage_/" + messages.type_hash(
        "tf2_msgs/msg/TFMessage"
    )
    assert tf.token == (
        "@ros2_lv/0/1f2e3d/0/1/MP/%/%robot_a/percept/%tf/tf2_msgs::msg::dds_::TFMessage_/"
        + messages.type_hash("tf2_msgs/msg/TFMessage")
        + "/::,:,:,:,,"
    )
    image = topics["camera/image/compressed"]
    assert image.name == "/robot_a/camera/image/compressed"
    assert image.key.startswith("0/robot_a/camera/image/compressed/sensor_msgs::msg::dds_::")
    assert dds_type("sensor_msgs/msg/JointState") == "sensor_msgs::msg::dds_::JointState_"
    assert (
        topic_key(7, "/x/y", "std_msgs/msg/String", "H") == "7/x/y/std_msgs::msg::dds_::String_/H"
    )


def test_published_samples_decode_to_the_world_model(router: tuple[zenoh.Session, int]) -> None:
    session, port = router
    received: dict[str, list[zenoh.Sample]] = {}
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        with lock:
            received.setdefault(str(sample.key_expr), []).append(sample)

    tokens: set[str] = set()
    session.declare_subscriber("0/**", on_sample)
    session.liveliness().declare_subscriber(
        "@ros2_lv/0/**", lambda s: tokens.add(str(s.key_expr)), history=True
    )
    publisher = Ros2Publisher(settings(port, image_rate=0.1), "robot-a", CAMERA)
    try:
        assert wait_for(lambda: len(tokens) == 1 + len(TOPICS), 10)
        assert publisher.node is not None
        wanted = {a.key: a for a in advertised(publisher.settings, publisher.node)}
        assert {a.token for a in wanted.values()} | {publisher.node.token()} == tokens
        image = np.random.default_rng(1).integers(0, 255, (144, 176, 3), dtype=np.uint8)
        worlds = [world(i) for i in range(1, 6)]
        for w in worlds:
            publisher.offer(w, {"head_pan": 0.25, "head_tilt": -0.5}, image)
            wait_for(lambda: publisher.samples["tf"] >= w.frame, 5)  # noqa: B023
        assert wait_for(lambda: len(received) == len(TOPICS), 10), sorted(received)
    finally:
        publisher.close()
    assert set(received) == set(wanted)
    by_topic = {wanted[k].topic: v for k, v in received.items()}
    assert len(by_topic["tf"]) == 5
    for sample, w in zip(by_topic["tf"], worlds, strict=True):
        check_tf(messages.deserialize(bytes(sample.payload), "tf2_msgs/msg/TFMessage"), w)
        seq, stamp, source = z_deserialize(tuple[Int64, Int64, bytes], sample.attachment)
        assert seq == w.frame and stamp > 1.7e18
        assert source == gid(wanted[str(sample.key_expr)].token)
    for sample, w in zip(by_topic["objects"], worlds, strict=True):
        check_objects(messages.deserialize(bytes(sample.payload), messages.TYPES["objects"]), w)
    joints = messages.deserialize(
        bytes(by_topic["joint_states"][0].payload), messages.TYPES["joint_states"]
    )
    assert list(joints.name) == ["head_pan", "head_tilt"]  # type: ignore[attr-defined]
    assert list(joints.position) == [0.25, -0.5]  # type: ignore[attr-defined]
    static = messages.deserialize(
        bytes(by_topic["tf_static"][0].payload), messages.TYPES["tf_static"]
    )
    (optical,) = static.transforms  # type: ignore[attr-defined]
    assert (optical.header.frame_id, optical.child_frame_id) == (
        "robot_a/camera",
        "robot_a/camera_optical",
    )
    np.testing.assert_allclose(
        quaternion_matrix(optical.transform.rotation), CAMERA_FROM_CV, atol=1e-12
    )
    # Images at most image_rate (one in 10 s): the five frames came faster than that.
    assert len(by_topic["camera/image/compressed"]) == 1
    jpeg = messages.deserialize(
        bytes(by_topic["camera/image/compressed"][0].payload),
        messages.TYPES["camera/image/compressed"],
    )
    assert jpeg.format == "jpeg" and jpeg.header.frame_id == "robot_a/camera_optical"  # type: ignore[attr-defined]
    info = messages.deserialize(
        bytes(by_topic["camera/camera_info"][0].payload), messages.TYPES["camera/camera_info"]
    )
    assert list(info.k) == CAMERA.K.ravel().tolist()  # type: ignore[attr-defined]
    assert (info.width, info.height) == (176, 144)  # type: ignore[attr-defined]
    # Closing withdraws the node and its publishers from the graph.
    assert wait_for(lambda: not list(session.liveliness().get("@ros2_lv/0/**", timeout=0.5)), 5)


def test_off_means_no_thread_and_no_session() -> None:
    """With [ros2] off the daemon gets no publisher: no thread, no session, rosbags not even
    imported (in a fresh interpreter, as the daemon's)."""
    script = (
        "import sys, threading\n"
        "from percept.runtime.daemon.daemon import Daemon\n"
        "from percept.runtime.ros2 import open_ros2\n"
        "from percept.runtime.ros2.settings import Ros2Settings\n"
        "before = threading.active_count()\n"
        "assert open_ros2(Ros2Settings(), 'a', None) is None\n"
        "assert threading.active_count() == before\n"
        "assert 'rosbags' not in sys.modules\n"
        "assert 'percept.runtime.ros2.publisher' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", script], check=True, timeout=120)


def test_ros2_settings_errors_name_file_and_key(tmp_path: Path) -> None:
    path = tmp_path / "e.toml"
    head = f'name = "x"\n[[robots]]\nname = "a"\nprofile = "{PROFILE}"\n'
    path.write_text(head + '[ros2]\nenabled = true\nnamespace = "robot a"\n')
    with pytest.raises(ConfigError, match=r"e\.toml: ros2\.namespace: expected a ROS 2 namespace"):
        load_experiment(path)
    path.write_text(head + "[ros2]\nenabled = true\n")  # both on tcp/127.0.0.1:7447
    with pytest.raises(
        ConfigError, match=r"ros2\.router: tcp/127\.0\.0\.1:7447 is a robot's endpoint"
    ):
        load_experiment(path)
    path.write_text(head + '[ros2]\ntopics = ["tf", "odom"]\n')
    with pytest.raises(ConfigError, match=r"ros2\.topics\[1\]: expected one of"):
        load_experiment(path)
    path.write_text(head + '[ros2]\nenabled = true\nrouter = "tcp/127.0.0.1:7448"\n')
    assert load_experiment(path).ros2.namespace_of("robot-a") == "/robot_a"
