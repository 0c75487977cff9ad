"""Example messages of every schema, for the tests of the codec, the link and the fuzzers."""

from __future__ import annotations

from percept.perception.landmarks.records import BoxPose
from percept.runtime.net.messages import (
    Boxes,
    Feedback,
    Guess,
    PeerPose,
    PointingAnswer,
    PointingRequest,
    Signal,
    Status,
    Utterance,
    World,
    WorldObject,
)

NOW = 1.7e9
WORLD = World(
    robot="a",
    stamp=NOW,
    frame=12,
    camera={"R": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "t": [0.0, 0.0, 0.45]},
    objects=(
        WorldObject(
            "o716",
            (10.0, 20.0, 30.0, 40.0),
            {"x": 0.5, "y": -0.1, "width": 0.05, "height": 0.07, "luminance": 120.0},
            {"x": 0.6, "y": 0.4},
            True,
            2.5,
            False,
        ),
        WorldObject(3, (0.0, 0.0, 5.0, 5.0), {"x": None, "y": None}, on_ground=False),
        WorldObject(
            "o9", (-40.0, 20.0, 25.0, 30.0), {"x": 0.6, "y": 0.5}, visible=False, last_seen=NOW - 12
        ),
    ),
    boxes=(BoxPose(1, 0.8, 0.1, 3.0, 2),),
    peers={"b": PeerPose(1.2, 0.3, 3.1, NOW, 1)},
)
MESSAGES = [
    Boxes("a", NOW, (BoxPose(1, 0.5, -0.2, -3.1, 1), BoxPose(2, 0.7, 0.2, 0.4, 3))),
    WORLD,
    Status("a", NOW, 29.5, 3, {"state": "ok"}, {"stale": []}, {"b": {"alive": True}}, 0, ("x",)),
    Status(
        "a",
        NOW,
        29.5,
        3,
        {},
        {},
        {},
        0,
        (),
        ms_per_frame=4.2,
        frames=900,
        old_joint_frames=2,
        frames_without_joints=1,
        background="calibrated on 60 frames",
        inbox_dropped=5,
        games={"played": 4, "success": 3, "as_speaker": 2},
        cpu=0.35,
        cpu_threads={"perception": 0.2, "camera": 0.06, "markers": 0.05, "other": 0.04},
        rss_mb=210.5,
        recording={"state": "recording", "file": "a.mcap"},
    ),
    World("a", NOW, 13, WORLD.camera, (), t=1234.5, pose_fresh=False),
    PointingRequest("g-1", "a", "b", 0.4, 0.1),
    PointingAnswer("g-1", "b", "a", "o12", 0.5, -0.3),
    PointingAnswer("g-1", "b", "a", None),
    Signal("g-1", "a", "b", "success"),
    Signal("g-2", "monitor", "a", "start", "a", "b"),
    Signal("g-3", "monitor", "b", "start", "a", "b", "guessing", ("o12", 3)),
    Utterance("g-3", "a", "b", "bodaki"),
    Guess("g-3", "b", "a", "o12", 0.5, -0.3),
    Guess("g-3", "b", "a", None),
    Feedback("g-3", "a", "b", "success"),
    Feedback("g-3", "a", "b", "failure", 0.4, 0.1),
]
