"""The peer's pose from shared boxes (SPEC §4.7), traded at 5 Hz between real Zenoh sessions."""

from __future__ import annotations

import math
import random

import pytest

from percept.kinematics.pose import wrap
from percept.perception.landmarks.records import BoxPose
from percept.runtime.net.link import Link
from percept.runtime.net.messages import Boxes, PeerPose
from percept.runtime.net.peers import (
    BoxPublisher,
    PeerTracker,
    inverse,
    peer_pose,
    to_my_frame,
    to_peer_frame,
)
from percept.runtime.net.settings import PeerSettings
from tests.support.polling import wait_for
from tests.support.zenoh_rig import experiment


def _in_frame(robot: tuple[float, float, float], box: tuple[int, float, float, float]) -> BoxPose:
    """A box given in the world, as the robot at ``robot`` (x, y, heading) sees it."""
    rx, ry, rt = robot
    i, bx, by, bt = box
    c, s = math.cos(rt), math.sin(rt)
    dx, dy = bx - rx, by - ry
    return BoxPose(i, c * dx + s * dy, -s * dx + c * dy, wrap(bt - rt), 2)


def _scene(rng: random.Random) -> tuple[list, tuple, tuple]:
    boxes = [(i, rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3)) for i in range(3)]
    a = (rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-math.pi, math.pi))
    b = (rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-math.pi, math.pi))
    return boxes, a, b


def _truth(a: tuple, b: tuple) -> tuple[float, float, float]:
    """Robot b's pose in robot a's frame."""
    seen = _in_frame(a, (0, b[0], b[1], b[2]))
    return seen.x, seen.y, seen.theta


@pytest.mark.parametrize("seed", range(20))
def test_formula_recovers_the_pose_exactly(seed: int) -> None:
    rng = random.Random(seed)
    boxes, a, b = _scene(rng)
    shared = boxes[: rng.randint(1, 3)]
    pose = peer_pose([_in_frame(a, x) for x in boxes], [_in_frame(b, x) for x in shared])
    assert pose is not None and pose.n_boxes == len(shared)
    x, y, theta = _truth(a, b)
    assert (pose.x, pose.y, wrap(pose.theta - theta)) == pytest.approx((x, y, 0.0), abs=1e-9)


def test_no_shared_box_no_pose() -> None:
    assert peer_pose([BoxPose(1, 1, 0, 0)], [BoxPose(2, 1, 0, 0)]) is None


def test_noisy_headings_are_averaged_on_the_circle() -> None:
    mine = [BoxPose(1, 1.0, 0.0, math.pi - 0.01), BoxPose(2, 0.0, 1.0, math.pi - 0.01)]
    theirs = [BoxPose(1, 1.0, 0.0, -0.03), BoxPose(2, 0.0, 1.0, 0.01)]  # truth: pi
    pose = peer_pose(mine, theirs)
    assert pose is not None and abs(wrap(pose.theta - math.pi)) < 0.011


def test_frames_round_trip() -> None:
    pose = PeerPose(0.7, -0.2, 2.5, 0.0, 1)
    assert to_peer_frame(pose, *to_my_frame(pose, 0.3, 0.4)) == pytest.approx((0.3, 0.4))
    back = inverse(inverse(pose))
    assert (back.x, back.y, back.theta) == pytest.approx((pose.x, pose.y, pose.theta))
    mine = inverse(pose)  # where I stand in the peer's frame maps to my origin
    assert to_my_frame(pose, mine.x, mine.y) == pytest.approx((0.0, 0.0), abs=1e-12)


def test_stale_and_gone_peers_have_no_pose() -> None:
    now = [0.0]
    tracker = PeerTracker(
        "a", lambda: [BoxPose(1, 1.0, 0.0, 0.0)], PeerSettings(stale_after=1.0), lambda: now[0]
    )
    tracker.on_boxes(Boxes("b", 1.0, (BoxPose(1, 1.0, 0.0, math.pi),)))
    assert tracker.pose("b") is not None
    now[0] = 1.5
    assert tracker.pose("b") is None and tracker.poses() == {}
    tracker.on_boxes(Boxes("b", 2.0, (BoxPose(1, 1.0, 0.0, math.pi),)))
    assert set(tracker.poses()) == {"b"}
    tracker.on_alive("b", False)
    assert tracker.pose("b") is None


def test_boxes_or_poses_beyond_the_arena_are_rejected_and_counted_by_sender() -> None:
    now = [0.0]
    mine = [BoxPose(1, 1.0, 0.0, 0.0)]
    tracker = PeerTracker("a", lambda: mine, PeerSettings(arena=20.0), lambda: now[0])
    good = Boxes("b", 1.0, (BoxPose(1, 1.0, 0.0, math.pi),))
    tracker.on_boxes(good)
    before = tracker.pose("b")
    assert before is not None and math.dist((before.x, before.y), (2.0, 0.0)) < 1e-9
    # The message: every field within the schema, the box 14 km from b.
    tracker.on_boxes(Boxes("b", 2.0, (BoxPose(1, 1e4, 1e4, 0.0),)))
    assert tracker.pose("b") == before  # the last plausible message still counts
    run = tracker.implausible()["b"]
    assert run.total == 1 and run.reason == "box 1 1.414e+04 m from it, beyond the arena (20 m)"
    # A box within the arena whose pose is not: me 1 m from the box, b 19.5 m from it.
    tracker.on_boxes(Boxes("b", 3.0, (BoxPose(1, -19.5, 0.0, 0.0),)))
    for _ in range(5):  # however many frames ask, one message counts once
        assert tracker.pose("b") is None and tracker.poses() == {}
    assert tracker.implausible()["b"].total == 2 and tracker.implausible()["b"].active(now[0])
    now[0] = 2.5  # a run ends 2 s after its last incident
    assert not tracker.implausible()["b"].active(now[0])
    tracker.on_boxes(good)
    assert tracker.pose("b") is not None and set(tracker.implausible()) == {"b"}


def test_box_stamps_far_from_their_arrival_are_rejected_and_counted() -> None:
    """The issue's stamps: 1970 and a day old, and one a minute ahead; within ten times
    stale_after of the arrival (clocks a few seconds apart) the boxes count."""
    mine = [BoxPose(1, 1.0, 0.0, 0.0)]
    tracker = PeerTracker("a", lambda: mine, PeerSettings(stale_after=1.0), lambda: 0.0)
    arrived = 1.8e9
    box = (BoxPose(1, 1.0, 0.0, math.pi),)
    for stamp in (0.0, arrived - 86400.0, arrived + 60.0):
        tracker.on_boxes(Boxes("b", stamp, box), arrived)
        assert tracker.pose("b") is None
    run = tracker.implausible()["b"]
    assert run.total == 3 and run.reason == "stamped 1.8e+09 s before it arrived, more than 10 s"
    tracker.on_boxes(Boxes("b", arrived - 9.0, box), arrived)
    assert tracker.pose("b") is not None
    tracker.on_boxes(Boxes("b", 0.0, box))  # no arrival time (a tool's tracker): not checked
    assert tracker.implausible()["b"].total == 3


@pytest.mark.timeout(60)
def test_real_sessions_trade_boxes_and_recover_random_poses() -> None:
    exp = experiment("a", "b")
    world: dict[str, list[BoxPose]] = {"a": [], "b": []}
    rng = random.Random(11)
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b:
        trackers = {}
        publishers = []
        for name, link in (("a", link_a), ("b", link_b)):
            # Stale only after 30 s: the end below must be noticed through liveliness.
            tracker = PeerTracker(
                name, lambda name=name: list(world[name]), PeerSettings(stale_after=30.0)
            )
            link.subscribe("boxes", tracker.on_boxes)
            link.watch_alive(tracker.on_alive)
            trackers[name] = tracker
            publishers.append(BoxPublisher(link, name, lambda name=name: list(world[name])).start())
        try:
            for _ in range(5):
                boxes, a, b = _scene(rng)
                world["a"] = [_in_frame(a, x) for x in boxes]
                world["b"] = [_in_frame(b, x) for x in boxes[1:]]
                x, y, theta = _truth(a, b)

                def exact(x=x, y=y, theta=theta) -> bool:
                    p = trackers["a"].pose("b")
                    q = trackers["b"].pose("a")
                    return (
                        p is not None
                        and q is not None
                        and abs(p.x - x) < 1e-6
                        and abs(p.y - y) < 1e-6
                        and abs(wrap(p.theta - theta)) < 1e-6
                        and abs(to_my_frame(q, p.x, p.y)[0]) < 1e-6
                        and abs(to_my_frame(q, p.x, p.y)[1]) < 1e-6
                    )

                assert wait_for(exact, 10.0)
            assert trackers["a"].pose("b").n_boxes == 2  # type: ignore[union-attr]
        finally:
            for p in publishers:
                p.stop()
        assert all(p.sent > 0 for p in publishers)
        link_b.close()
        assert wait_for(lambda: trackers["a"].pose("b") is None, 1.0)
