"""The guessing game between robots over real Zenoh sessions: its messages checked and counted,
rounds between two game endpoints, and the joint-attention monitor starting games on a partly
occluded scene."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from zenoh import CongestionControl

from percept.runtime.games.language.dataset.contexts import SHARED_CHANNELS
from percept.runtime.games.language.live import GuessingGames, things
from percept.runtime.games.monitor import AttentionMonitor, MonitorService, shared_objects
from percept.runtime.games.pointing import Located
from percept.runtime.net.link import Link
from percept.runtime.net.messages import (
    Feedback,
    Utterance,
    World,
    WorldObject,
    encode,
)
from percept.runtime.net.settings import PeerSettings
from tests.support.polling import wait_for
from tests.support.poses import Pose, relative, seen_from
from tests.support.zenoh_rig import experiment

A: Pose = (-0.8, 0.1, 0.2)
B: Pose = (0.7, -0.2, math.pi - 0.3)
TOPICS = ("utterance", "guess", "feedback", "signal")


def _scene(seed: int, n: int = 5) -> list[tuple[float, float, tuple[float, ...]]]:
    """``n`` objects 10 cm apart at least, each with values on the shared channels."""
    rng = random.Random(seed)
    out: list[tuple[float, float, tuple[float, ...]]] = []
    while len(out) < n:
        x, y = rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3)
        if all(math.dist((x, y), o[:2]) >= 0.1 for o in out):
            out.append((x, y, tuple(rng.random() for _ in SHARED_CHANNELS)))
    return out


def _world(robot: str, pose: Pose, peer: str, scene, seen: range) -> World:
    """Robot ``robot``'s world model of the objects ``seen`` (the others hidden from it), under
    its own anchor ids, with the peer's exact pose."""
    objects = []
    for i in seen:
        x, y, values = scene[i]
        mx, my = seen_from(pose, x, y)
        scaled: dict[str, float | None] = dict(zip(SHARED_CHANNELS, values, strict=True))
        objects.append(
            WorldObject(f"{robot}{i + 3}", (0.0, 0.0, 9.0, 9.0), {"x": mx, "y": my}, scaled)
        )
    camera = {"R": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "t": [0.0, 0.0, 0.45]}
    other = B if robot == "a" else A
    return World(robot, 1.7e9, 1, camera, tuple(objects), (), {peer: relative(pose, other)})


def _endpoints(links: dict[str, Link], worlds: dict[str, World], settings: PeerSettings, **kw):
    poses = {"a": relative(A, B), "b": relative(B, A)}
    return {
        name: GuessingGames(
            link,
            lambda n=name: things(worlds[n]),
            lambda peer, n=name: poses[n],
            settings,
            np.random.default_rng(ord(name)),
            **kw,
        )
        for name, link in links.items()
    }


def _listened(*links: Link) -> bool:
    return all(link.listened(topic) for link in links for topic in TOPICS)


def test_things_of_a_world_model() -> None:
    scene = _scene(1, 3)
    world = _world("a", A, "b", scene, range(3))
    got = things(world)
    assert [t.id for t in got] == ["a3", "a4", "a5"]
    assert got[1].values == pytest.approx(scene[1][2])
    assert (got[1].x, got[1].y) == pytest.approx(seen_from(A, *scene[1][:2]))
    assert things(None) == []


@pytest.mark.timeout(90)
def test_guessing_games_between_two_endpoints_complete_and_learn() -> None:
    """Rounds of the live game between two robots' endpoints: each round completes on both
    sides with the same outcome, and the agents learn across rounds."""
    scenes = [_scene(seed) for seed in range(6)]
    worlds: dict[str, World] = {}
    settings = PeerSettings(pointing_gate=0.05, answer_timeout=5.0)
    exp = experiment("a", "b")
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b:
        games = _endpoints({"a": link_a, "b": link_b}, worlds, settings, players=("a", "b"))
        assert wait_for(lambda: _listened(link_a, link_b))
        results = []
        for k in range(240):
            scene = scenes[k % len(scenes)]
            worlds["a"] = _world("a", A, "b", scene, range(5))
            worlds["b"] = _world("b", B, "a", scene, range(5))
            speaker, hearer = ("a", "b") if k % 2 == 0 else ("b", "a")
            result = games[speaker].play(hearer)
            assert result.reason != "no answer", result
            if result.topic is not None and result.reason != "no category tells the topic apart":
                # the hearer's side of the same round ends with the same outcome
                assert wait_for(
                    lambda h=hearer, r=result: any(x.game == r.game for x in games[h].results)
                )
                heard = next(x for x in games[hearer].results if x.game == result.game)
                assert heard.role == "hearer" and heard.outcome == result.outcome
            results.append(result.outcome == "success")
        late, early = np.mean(results[-60:]), np.mean(results[:30])
        assert late >= 0.8 > early, (late, early)
        for g in games.values():
            assert g.played > 200 and g.lexicon_size > 0 and g.categories > 0, g.played
            assert g.unsent == 0 and not g.ignored
        assert link_a.rejected == link_b.rejected == 0


@pytest.mark.timeout(60)
def test_malformed_utterances_and_feedback_are_rejected_and_counted() -> None:
    exp = experiment("a", "b")
    worlds = {"a": _world("a", A, "b", _scene(2), range(5))}
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b, Link(exp, "c0", listen=[]) as other:
        (games,) = _endpoints({"a": link_a}, worlds, PeerSettings(), players=("a", "b")).values()
        assert wait_for(lambda: _listened(link_b))
        bad = {
            "percept/b/utterance": [
                b'{"schema": "percept.utterance/1", "game": "g", "from": "b", "to": "a"}',
                b'{"schema":"percept.utterance/1","game":"g","from":"b","to":"a","word":"Ba Da"}',
                encode(Feedback("g", "b", "a", "success")),  # right message, wrong key
                b"\xff not json",
            ],
            "percept/b/feedback": [
                b'{"schema":"percept.feedback/1","game":"g","from":"b","to":"a","signal":"yes"}',
                b'{"schema":"percept.feedback/1","game":"g","from":"b","to":"a",'
                b'"signal":"failure","x":1e300,"y":0}',
                encode(Feedback("g", "c0", "a", "failure")),  # c0 speaking on b's key
            ],
        }
        for key, payloads in bad.items():
            for payload in payloads:
                # blocking: Zenoh's default drops a put on a congested queue, and each is counted
                link_b.session.put(key, payload, congestion_control=CongestionControl.BLOCK)
        assert wait_for(lambda: link_a.rejected == 7)
        assert link_a.rejected_by_key["percept/b/utterance"] == 4
        assert link_a.rejected_by_key["percept/b/feedback"] == 3
        # A well-formed utterance from a robot that is not a player is ignored and counted.
        assert wait_for(lambda: other.listened("utterance"))
        other.publish("utterance", Utterance("g2", "c0", "a", "bada"))
        assert wait_for(lambda: games.ignored["c0"] == 1)
        # None of it reached a game: the robot heard nothing and said nothing.
        assert games.played == 0 and games.lexicon_size == 0
        assert link_b.rejected == 0


def test_shared_context_leaves_out_what_one_robot_does_not_see() -> None:
    mine = [Located(1, 0.0, 0.0), Located(2, 0.2, 0.0), Located(3, 0.4, 0.0)]
    theirs = [Located(8, 0.21, 0.01), Located(9, 0.01, 0.0), Located(7, 0.9, 0.9)]
    assert shared_objects(mine, theirs, 0.05) == [(1, 9), (2, 8)]
    assert shared_objects(mine, theirs, 0.05, least=3) is None
    assert shared_objects(mine, [], 0.05) is None


@pytest.mark.parametrize(("rule", "joint"), [("shared", True), ("same", False)])
def test_the_rules_on_a_partly_occluded_scene(rule: str, joint: bool) -> None:
    scene = _scene(3)
    events: list[dict] = []
    settings = PeerSettings(attention=rule)  # type: ignore[arg-type]
    monitor = AttentionMonitor(["a", "b"], settings, events.append)
    monitor.on_world(_world("a", A, "b", scene, range(0, 4)))  # object 4 hidden from a
    monitor.on_world(_world("b", B, "a", scene, range(1, 5)))  # object 0 hidden from b
    assert bool(events) is joint
    if joint:
        assert sorted(map(tuple, events[0]["objects"])) == [
            ("a4", "b4"),
            ("a5", "b5"),
            ("a6", "b6"),
        ]


@pytest.mark.timeout(90)
def test_monitor_starts_guessing_games_on_a_partly_occluded_scene() -> None:
    """Each robot sees an object the other does not: the monitor starts guessing games about
    the three both see, again and again, and the robots play them over Zenoh."""
    scene = _scene(4)
    worlds = {
        "a": _world("a", A, "b", scene, range(0, 4)),
        "b": _world("b", B, "a", scene, range(1, 5)),
    }
    settings = PeerSettings(games=("guessing",), game_interval=0.3, stale_after=30.0)
    events: list[dict] = []
    exp = experiment("a", "b")
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b, Link(exp, "monitor") as link_m:
        MonitorService(link_m, ["a", "b"], settings, events.append)
        games = _endpoints({"a": link_a, "b": link_b}, worlds, settings, players=("a", "b"))
        assert wait_for(lambda: _listened(link_a, link_b) and link_m.listened("signal"))

        def publish() -> bool:
            link_a.publish("world", worlds["a"])
            link_b.publish("world", worlds["b"])
            return sum(g.played for g in games.values()) >= 8

        assert wait_for(publish, 30.0)
    assert events[0]["event"] == "joint_attention" and events[0]["play"] == "guessing"
    assert {e["event"] for e in events[1:]} <= {"game"} and len(events) >= 4
    assert all(len(e["objects"]) == 3 for e in events)
    started = {e["game"] for e in events}
    for g in games.values():
        assert {r.game for r in g.results} <= started
        assert g.as_speaker >= 1 and g.played - g.as_speaker >= 1
        # the topics are of the shared context: never the object the other robot cannot see
        assert all(r.topic not in ("a3", "b7") for r in g.results if r.role == "speaker")


def test_a_pair_beyond_the_gate_does_not_steer_the_others() -> None:
    # Least total distance over all pairings would take (1, 8) and (2, 9), 0.5 + 0.17 against
    # 0.03 + 0.7, and neither is within the gate; (1, 9) is.
    mine = [Located(1, 0.0, 0.0), Located(2, 0.2, 0.0)]
    theirs = [Located(9, 0.03, 0.0), Located(8, -0.5, 0.0)]
    assert shared_objects(mine, theirs, 0.05) == [(1, 9)]
