"""``percept run --sim`` with ``[ros2]`` enabled: a plain Zenoh router stands in for rmw_zenohd,
and the camera pose on ``/tf`` equals the one in the same frame's ``percept.world`` message on
the robot's own key (which the ROS 2 side leaves as it was)."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
import zenoh

from percept.runtime.ros2 import messages
from tests.runtime.daemon.test_daemon import Listener
from tests.runtime.ros2.test_ros2 import quaternion_matrix
from tests.support.daemon import endpoint, experiment_copy, start_daemon, stop
from tests.support.zenoh_rig import free_port


@pytest.mark.timeout(240)
def test_the_daemon_publishes_its_world_on_ros2(tmp_path: Path) -> None:
    port = free_port()
    router = zenoh.open(
        zenoh.Config.from_json5(
            f'{{mode: "router", listen: {{endpoints: ["tcp/127.0.0.1:{port}"]}},'
            " scouting: {multicast: {enabled: false}}}"
        )
    )
    tf: list[zenoh.Sample] = []
    tokens: set[str] = set()
    lock = threading.Lock()

    def on_tf(sample: zenoh.Sample) -> None:
        with lock:
            tf.append(sample)

    router.declare_subscriber("0/tf/**", on_tf)
    router.liveliness().declare_subscriber(
        "@ros2_lv/0/**", lambda s: tokens.add(str(s.key_expr)), history=True
    )
    experiment = experiment_copy(tmp_path)
    with experiment.open("a", encoding="utf-8") as fh:
        fh.write(f'\n[ros2]\nenabled = true\nrouter = "tcp/127.0.0.1:{port}"\n')
    proc = start_daemon(experiment, "a")
    listener = Listener(endpoint(experiment, "a"), "a")
    try:
        got = listener.wait(lambda s: len(s.worlds) >= 5 and len(tf) >= 5, 180)
    finally:
        # Stopped this early (still calibrating) the daemon outlives stop()'s 10 s with or
        # without [ros2]: its exit code is not this test's business.
        _, _, err = stop(proc)
        listener.close()
    ros2_lines = [line for line in err.splitlines() if "ROS 2" in line]
    assert got, (len(listener.worlds), len(tf), sorted(tokens), ros2_lines, err[-1500:])
    assert any(t.endswith("/NN/%/%a/percept") for t in tokens), tokens
    worlds = {round(w["stamp"], 6): w for w in listener.worlds}
    matched = 0
    with lock:
        samples = list(tf)
    for sample in samples:
        message = messages.deserialize(bytes(sample.payload), "tf2_msgs/msg/TFMessage")
        (camera,) = [t for t in message.transforms if t.child_frame_id == "a/camera"]  # type: ignore[attr-defined]
        stamp = camera.header.stamp.sec + camera.header.stamp.nanosec * 1e-9
        world = worlds.get(round(stamp, 6))
        if world is None:  # world_rate sends fewer world messages than frames
            continue
        t = camera.transform.translation
        np.testing.assert_allclose([t.x, t.y, t.z], world["camera"]["t"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(
            quaternion_matrix(camera.transform.rotation), world["camera"]["R"], rtol=0, atol=1e-9
        )
        matched += 1
    router.close()
    assert matched >= 3, (matched, len(samples), len(worlds))
