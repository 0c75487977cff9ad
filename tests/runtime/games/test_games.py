"""The pointing game (speaker and hearer machines) and the joint-attention monitor, over real
Zenoh sessions."""

from __future__ import annotations

import json
import math
import os
import random
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from percept.perception.landmarks.records import BoxPose
from percept.runtime.games.monitor import AttentionMonitor, MonitorService, same_objects
from percept.runtime.games.pointing import (
    Hearer,
    Located,
    PointingGames,
    Speaker,
    located,
    nearest,
)
from percept.runtime.games.service import RESULTS_KEPT
from percept.runtime.net.link import Link
from percept.runtime.net.messages import (
    PeerPose,
    PointingAnswer,
    PointingRequest,
    Signal,
    World,
    WorldObject,
)
from percept.runtime.net.peers import BoxPublisher, PeerTracker, inverse
from percept.runtime.net.settings import PeerSettings
from tests.support.polling import wait_for
from tests.support.poses import Pose, relative, seen_from
from tests.support.zenoh_rig import PROFILE, experiment

REPO = Path(__file__).resolve().parents[3]


def _objects(rng: random.Random, n: int, spacing: float = 0.1) -> list[tuple[float, float]]:
    """``n`` object positions in the world, at least ``spacing`` apart."""
    points: list[tuple[float, float]] = []
    while len(points) < n:
        p = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3))
        if all(math.dist(p, q) >= spacing for q in points):
            points.append(p)
    return points


def _view(robot: Pose, points: list[tuple[float, float]], tag: str) -> list[Located]:
    """What a robot sees: the objects in its frame, under its own anchor ids."""
    return [Located(f"{tag}{i + 7}", *seen_from(robot, *p)) for i, p in enumerate(points)]


def test_nearest_respects_the_gate() -> None:
    objects = [Located("o1", 0.0, 0.0), Located("o2", 0.3, 0.0)]
    assert nearest(objects, 0.1, 0.0, 0.15).id == "o1"  # type: ignore[union-attr]
    assert nearest(objects, 0.15, 0.2, 0.15) is None
    assert nearest([], 0.0, 0.0, 1.0) is None


def test_past_the_gate_only_an_unambiguous_nearest_object() -> None:
    """Between one and two gates from the place the nearest object is taken when the next is
    at least twice as far; never beyond two gates."""
    alone = [Located("o1", 0.075, 0.0), Located("o2", -0.2, 0.0)]  # 7.5 and 20 cm away
    assert nearest(alone, 0.0, 0.0, 0.05).id == "o1"  # type: ignore[union-attr]
    crowded = [Located("o1", 0.075, 0.0), Located("o2", -0.12, 0.0)]  # 7.5 and 12 cm away
    assert nearest(crowded, 0.0, 0.0, 0.05) is None
    assert nearest([Located("o1", 0.11, 0.0)], 0.0, 0.0, 0.05) is None
    # Two anchors of one object (within a gate of each other) are one place, not two candidates.
    twice = [Located("o1", 0.075, 0.0), Located("o3", 0.09, 0.01), Located("o2", -0.2, 0.0)]
    assert nearest(twice, 0.0, 0.0, 0.05).id == "o1"  # type: ignore[union-attr]


def test_an_answer_at_another_anchor_of_the_topic_wins() -> None:
    """The speaker holds two anchors of its topic 3 cm apart (a shaded part anchored apart):
    the hearer's choice mapped onto the other anchor is the topic; onto an object 12 cm away,
    it is another object."""
    mine = [Located("o1", 0.5, 0.0), Located("o2", 0.53, 0.0), Located("o3", 0.5, 0.12)]
    facing = PeerPose(1.0, 0.0, math.pi, 0.0, 1)  # the hearer 1 m ahead, facing me
    # The hearer's answers in its frame: (0.47, 0) is my (0.53, 0), o2; (0.5, -0.12) is o3.
    for answer, outcome in (((0.47, 0.0), "success"), ((0.5, -0.12), "failure")):
        speaker = Speaker("g", "a", "b", lambda: mine, lambda _: facing, 0.05, random.Random(1))
        speaker.topic = mine[0]
        assert speaker.point() == [PointingRequest("g", "a", "b", 0.5, 0.0)]
        (verdict,) = speaker.on_answer(PointingAnswer("g", "b", "a", "b7", *answer))
        assert verdict.signal == outcome, speaker.result


@pytest.mark.parametrize("seed", range(10))
def test_machines_win_with_exact_poses(seed: int) -> None:
    rng = random.Random(seed)
    a = (rng.uniform(-1, -0.6), rng.uniform(-0.3, 0.3), rng.uniform(-0.5, 0.5))
    b = (rng.uniform(0.6, 1), rng.uniform(-0.3, 0.3), math.pi + rng.uniform(-0.5, 0.5))
    points = _objects(rng, 5)
    seen_a, seen_b = _view(a, points, "a"), _view(b, points, "b")
    speaker = Speaker("g", "a", "b", lambda: seen_a, lambda _: relative(a, b), 0.05, rng)
    hearer = Hearer("g", "b", "a", lambda: seen_b, lambda _: relative(b, a), 0.05)
    (request,) = speaker.start()
    assert isinstance(request, PointingRequest) and speaker.state == "pointing"
    (answer,) = hearer.on_request(request)
    assert isinstance(answer, PointingAnswer)
    assert answer.object == "b" + speaker.topic.id[1:]  # type: ignore[union-attr]
    (verdict,) = speaker.on_answer(answer)
    assert verdict == Signal("g", "a", "b", "success")
    hearer.on_signal(verdict)
    assert speaker.result.outcome == hearer.result.outcome == "success"  # type: ignore[union-attr]


@pytest.mark.parametrize("seed", range(5))
def test_the_hearer_may_choose_an_object_it_remembers(seed: int) -> None:
    """The speaker points only at what it sees; the hearer, looking elsewhere, answers with the
    object it remembers there, and the game is won."""
    rng = random.Random(seed)
    a = (rng.uniform(-1, -0.6), rng.uniform(-0.3, 0.3), rng.uniform(-0.5, 0.5))
    b = (rng.uniform(0.6, 1), rng.uniform(-0.3, 0.3), math.pi + rng.uniform(-0.5, 0.5))
    points = _objects(rng, 4)
    # a remembers all but the first: it can only point at that one.
    seen_a = [replace(o, visible=i == 0) for i, o in enumerate(_view(a, points, "a"))]
    seen_b = [replace(o, visible=False) for o in _view(b, points, "b")]  # b looks away
    speaker = Speaker("g", "a", "b", lambda: seen_a, lambda _: relative(a, b), 0.05, rng)
    hearer = Hearer("g", "b", "a", lambda: seen_b, lambda _: relative(b, a), 0.05)
    (request,) = speaker.start()
    assert speaker.topic is not None and speaker.topic.id == "a7"
    (answer,) = hearer.on_request(request)
    assert isinstance(answer, PointingAnswer) and answer.object == "b7"
    assert speaker.on_answer(answer) == [Signal("g", "a", "b", "success")]
    # Remembering is not seeing: nothing seen, nothing to point at.
    assert Speaker("h", "b", "a", lambda: seen_b, lambda _: None, 0.05, rng).start()[0] == Signal(
        "h", "b", "a", "failure"
    )


def test_the_speaker_points_where_it_sees_its_topic_after_looking() -> None:
    """Between choosing its topic and pointing the speaker looks at it: it points where it sees
    it then; an anchor made anew in the turn (another id, the same place) is the topic; with
    nothing seen there the game fails."""
    world = [Located("o1", 0.5, 0.1), Located("o2", 0.8, -0.2)]
    rng = random.Random(3)

    def speaker(game: str) -> tuple[Speaker, Located]:
        s = Speaker(game, "a", "b", lambda: list(world), lambda _: None, 0.05, rng)
        topic = s.choose()
        assert topic is not None
        return s, topic

    first, topic = speaker("g")
    world[:] = [replace(o, x=o.x + 0.01) if o.id == topic.id else o for o in world]
    assert first.point() == [PointingRequest("g", "a", "b", topic.x + 0.01, topic.y)]
    second, topic = speaker("h")
    anew = Located("o9", topic.x + 0.02, topic.y)
    world[:] = [anew if o.id == topic.id else o for o in world] + [replace(topic, visible=False)]
    assert second.point() == [PointingRequest("h", "a", "b", anew.x, anew.y)]
    assert second.topic == anew
    third, topic = speaker("i")
    world[:] = [o for o in world if math.dist((o.x, o.y), (topic.x, topic.y)) > 0.05]
    assert third.point() == [Signal("i", "a", "b", "failure")]
    assert third.result.reason == "the speaker does not see its topic"  # type: ignore[union-attr]


def test_located_objects_say_whether_they_are_seen() -> None:
    world = World(
        "a",
        1.0,
        1,
        {"R": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "t": [0.0, 0.0, 0.4]},
        (
            WorldObject("o1", (0, 0, 5, 5), {"x": 0.5, "y": 0.1}),
            WorldObject("o2", (-9, 0, 5, 5), {"x": 0.4, "y": 0.6}, visible=False, last_seen=0.5),
        ),
    )
    assert located(world) == [Located("o1", 0.5, 0.1), Located("o2", 0.4, 0.6, visible=False)]


def test_machines_fail_gracefully_without_poses() -> None:
    rng = random.Random(1)
    mine = [Located("o1", 0.5, 0.0)]
    # The hearer does not know where the speaker stands: it answers null.
    speaker = Speaker(
        "g", "a", "b", lambda: mine, lambda _: PeerPose(1, 0, math.pi, 0, 1), 0.1, rng
    )
    hearer = Hearer("g", "b", "a", lambda: mine, lambda _: None, 0.1)
    (answer,) = hearer.on_request(*speaker.start())
    assert answer == PointingAnswer("g", "b", "a", None)
    assert speaker.on_answer(answer) == [Signal("g", "a", "b", "failure")]
    assert speaker.result.reason == "the hearer found no object there"  # type: ignore[union-attr]
    # The speaker does not know where the hearer stands: it cannot check, so it fails.
    speaker = Speaker("h", "a", "b", lambda: mine, lambda _: None, 0.1, rng)
    speaker.start()
    speaker.on_answer(PointingAnswer("h", "b", "a", "o9", 0.5, 0.0))
    assert speaker.result.outcome == "failure"  # type: ignore[union-attr]
    assert "pose" in speaker.result.reason  # type: ignore[union-attr]
    # Nothing to talk about, or no answer in time.
    assert Speaker("i", "a", "b", list, lambda _: None, 0.1, rng).start()[0].signal == "failure"
    late = Speaker("j", "a", "b", lambda: mine, lambda _: None, 0.1, rng)
    late.start()
    assert late.on_timeout()[0].signal == "failure" and late.on_timeout() == []


def _robots(rng: random.Random) -> tuple[Pose, Pose, list[tuple[int, float, float, float]]]:
    a = (rng.uniform(-1, -0.6), rng.uniform(-0.4, 0.4), rng.uniform(-0.6, 0.6))
    b = (rng.uniform(0.6, 1), rng.uniform(-0.4, 0.4), math.pi + rng.uniform(-0.6, 0.6))
    boxes = [(i, rng.uniform(-0.5, 0.5), rng.uniform(0.4, 0.6), rng.uniform(-3, 3)) for i in (1, 2)]
    return a, b, boxes


def _boxes_seen(robot: Pose, boxes: list[tuple[int, float, float, float]]) -> list[BoxPose]:
    return [
        BoxPose(i, *seen_from(robot, x, y), math.remainder(t - robot[2], math.tau), 1)
        for i, x, y, t in boxes
    ]


@pytest.mark.timeout(90)
def test_pointing_games_over_zenoh() -> None:
    rng = random.Random(5)
    a, b, boxes = _robots(rng)
    points = _objects(rng, 6)
    exp = experiment("a", "b")
    settings = PeerSettings(pointing_gate=0.05, answer_timeout=5.0)
    seen = {"a": _view(a, points, "a"), "b": _view(b, points, "b")}
    box_view = {"a": _boxes_seen(a, boxes), "b": _boxes_seen(b, boxes)}
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b:
        games = {}
        publishers = []
        trackers = {}
        for name, link in (("a", link_a), ("b", link_b)):
            trackers[name] = tracker = PeerTracker(name, lambda n=name: box_view[n], settings)
            link.subscribe("boxes", tracker.on_boxes)
            publishers.append(BoxPublisher(link, name, lambda n=name: box_view[n]).start())
            games[name] = PointingGames(
                link, lambda n=name: seen[n], tracker.pose, settings, random.Random(name)
            )
        try:
            assert wait_for(lambda: trackers["a"].pose("b") and trackers["b"].pose("a"))
            assert wait_for(
                lambda: all(
                    link.listened(topic)
                    for link in (link_a, link_b)
                    for topic in ("pointing", "signal")
                )
            )
            results = [games["a"].play("b") for _ in range(10)]
            results += [games["b"].play("a") for _ in range(10)]
            assert [r.outcome for r in results] == ["success"] * 20, results
            assert wait_for(lambda: len(games["a"].results) == len(games["b"].results) == 20)
            heard = [r for r in games["b"].results if r.role == "hearer"]
            assert all(r.outcome == "success" and r.chosen for r in heard)
            # b stops hearing a's boxes: it no longer knows a's pose, and the game fails well.
            box_view["a"] = []
            assert wait_for(lambda: trackers["b"].pose("a") is None)
            failed = games["a"].play("b")
            assert (
                failed.outcome == "failure" and failed.reason == "the hearer found no object there"
            )
            assert wait_for(lambda: games["b"].results[-1].reason.startswith("the hearer does not"))
        finally:
            for p in publishers:
                p.stop()


@pytest.mark.timeout(60)
def test_games_only_with_the_players_results_bounded(caplog: pytest.LogCaptureFixture) -> None:
    """Requests and verdicts from made-up robots cost a count each, not a game; a start signal
    naming a hearer outside the players plays nothing; the results window and the game log
    lines stay bounded however many games are played."""
    exp = experiment("a", "b")
    with Link(exp, "a") as link_a, Link(exp, "c0", listen=[]) as stranger:
        games = PointingGames(link_a, list, lambda _: None, players=("a", "b"))
        assert games.players == {"b"}
        assert wait_for(lambda: stranger.listened("pointing") and stranger.listened("signal"))
        for i in range(50):
            stranger.publish("pointing", PointingRequest(f"g{i}", "c0", "a", 0.5, 0.0))
            stranger.publish("signal", Signal(f"g{i}", "c0", "a", "success"))
        stranger.publish("signal", Signal("s", "c0", "a", "start", speaker="a", hearer="c0"))
        assert wait_for(lambda: games.ignored["c0"] == 101)
        assert games.played == 0 and not games.results
        assert sum("ignoring pointing games with c0" in r.getMessage() for r in caplog.records) == 1
    # Played directly, as a speaker without objects: each game ends at once, in failure.
    with Link(exp, "a") as link_a:
        games = PointingGames(link_a, list, lambda _: None, players=("b",))
        with caplog.at_level("INFO", logger="percept.games"):
            caplog.clear()
            for _ in range(RESULTS_KEPT + 50):
                games.play("b")
        assert games.played == RESULTS_KEPT + 50 and len(games.results) == RESULTS_KEPT
        lines = [r.getMessage() for r in caplog.records if r.name == "percept.games"]
        assert len(lines) == 20  # at most 20 lines in 10 s


def _world(robot: str, pose: Pose, peer: str, peer_pose: PeerPose | None, points) -> World:
    objects = tuple(
        WorldObject(o.id, (0.0, 0.0, 10.0, 10.0), {"x": o.x, "y": o.y})
        for o in _view(pose, points, robot)
    )
    peers = {peer: peer_pose} if peer_pose else {}
    camera = {"R": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "t": [0.0, 0.0, 0.45]}
    return World(robot, 1.7e9, 1, camera, objects, (), peers)


def test_same_objects_is_one_to_one_within_the_gate() -> None:
    mine = [Located(1, 0.0, 0.0), Located(2, 0.2, 0.0)]
    assert same_objects(mine, [Located(9, 0.21, 0.01), Located(8, 0.01, 0.0)], 0.05) == [
        (1, 8),
        (2, 9),
    ]
    assert same_objects(mine, [Located(9, 0.21, 0.0), Located(8, 0.3, 0.0)], 0.05) is None
    assert same_objects(mine, [Located(9, 0.0, 0.0)], 0.05) is None
    assert same_objects([], [], 0.05) is None


def test_monitor_announces_joint_attention_and_its_end() -> None:
    """The chapter's rule: both see the same set of objects."""
    rng = random.Random(2)
    a, b, _ = _robots(rng)
    points = _objects(rng, 4)
    events: list[dict] = []
    settings = PeerSettings(attention_gate=0.05, attention="same")
    monitor = AttentionMonitor(["a", "b"], settings, events.append)
    monitor.on_world(_world("a", a, "b", relative(a, b), points))
    assert events == []
    # b's own estimate of a is enough: the monitor inverts it.
    monitor.on_world(_world("b", b, "a", relative(b, a), points))
    assert [e["event"] for e in events] == ["joint_attention"]
    assert len(events[0]["objects"]) == 4
    monitor.on_world(_world("a", a, "b", None, points))
    assert len(events) == 1  # still joint, through b's estimate
    monitor.on_world(_world("b", b, "a", relative(b, a), points[:3]))
    assert [e["event"] for e in events] == ["joint_attention", "attention_lost"]
    monitor.on_world(_world("b", b, "a", relative(b, a), points))
    monitor.on_alive("b", False)
    assert events[-1]["event"] == "attention_lost" and monitor.joint() == []
    assert inverse(relative(a, b)).x == pytest.approx(relative(b, a).x)


@pytest.mark.timeout(90)
def test_monitor_starts_a_game_between_robots() -> None:
    rng = random.Random(3)
    a, b, _ = _robots(rng)
    points = _objects(rng, 3)
    exp = experiment("a", "b")
    settings = PeerSettings(pointing_gate=0.05, attention_gate=0.05, stale_after=30.0)
    poses = {"a": relative(a, b), "b": relative(b, a)}
    events: list[dict] = []
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b, Link(exp, "monitor") as link_m:
        MonitorService(link_m, ["a", "b"], settings, events.append)
        games = {
            name: PointingGames(
                link,
                lambda n=name, p=pose: _view(p, points, n),
                lambda _, n=name: poses[n],
                settings,
            )
            for name, link, pose in (("a", link_a, a), ("b", link_b, b))
        }

        # The monitor's start and the robots' pointing must find their subscribers.
        links = (link_a, link_b, link_m)
        assert wait_for(lambda: all(link.listened("signal") for link in links))
        assert wait_for(lambda: link_a.listened("pointing") and link_b.listened("pointing"))

        def publish() -> bool:
            link_a.publish("world", _world("a", a, "b", poses["a"], points))
            link_b.publish("world", _world("b", b, "a", poses["b"], points))
            return bool(events)

        assert wait_for(publish, 20.0)
        assert events[0]["event"] == "joint_attention" and events[0]["speaker"] in ("a", "b")
        assert wait_for(lambda: games["a"].results and games["b"].results, 20.0)
        assert games["a"].results[0].outcome == "success"
        assert games["a"].results[0].game == events[0]["game"]


@pytest.mark.timeout(90)
def test_monitor_command_prints_json_lines(tmp_path: Path) -> None:
    exp = experiment("a", "b")
    robots = "".join(
        f'[[robots]]\nname = "{r.name}"\nprofile = "{PROFILE}"\nendpoint = "{r.endpoint}"\n'
        for r in exp.robots
    )
    toml = tmp_path / "e.toml"
    toml.write_text(
        f'name = "t"\n{robots}[peers]\nattention_gate = 0.05\nstale_after = 30.0\n',
        encoding="utf-8",
    )
    rng = random.Random(4)
    a, b, _ = _robots(rng)
    points = _objects(rng, 2)
    monitor = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "percept.runtime.cli",
            "monitor",
            "--experiment",
            str(toml),
            "--no-start",
        ],
        env={**os.environ, "PYTHONPATH": str(REPO)},
        stdout=subprocess.PIPE,
        encoding="utf-8",
    )
    try:
        with Link(exp, "a") as link_a, Link(exp, "b") as link_b:
            link_a.watch_alive(lambda *_: None)
            assert wait_for(lambda: link_a.alive("monitor"), 30.0)
            for _ in range(10):  # a second of world models
                link_a.publish("world", _world("a", a, "b", relative(a, b), points))
                link_b.publish("world", _world("b", b, "a", relative(b, a), points))
                time.sleep(0.1)
            monitor.terminate()
            out, _ = monitor.communicate(timeout=20)
    finally:
        monitor.kill()
        monitor.wait()
    events = [json.loads(line) for line in out.splitlines()]
    assert events and events[0]["event"] == "joint_attention" and events[0]["robots"] == ["a", "b"]
    assert monitor.returncode == 0
