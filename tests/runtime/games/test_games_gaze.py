"""The pointing game with heads that turn: each robot's head is the real chain (gaze, the
Dynamixel driver's writes through dynamixel-sdk, the emulated servos on a pty, which move at the
profile velocity), the games run over real Zenoh sessions, and perception is stood in for by a
thread that, thirty times a second, looks through the camera pose of the servos' present angles
(forward kinematics) and puts in the robot's world model every object within the lens's opening:
seen while in view, remembered once out of it, unknown until first seen."""

from __future__ import annotations

import itertools
import math
import random
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pytest
from zenoh import CongestionControl

from percept.config.loader import load
from percept.drivers.dynamixel.bus import DynamixelBus, radians_to_ticks
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.settings import GazeSettings
from percept.drivers.sim.scene import Scene
from percept.kinematics.tree import KinematicTree
from percept.runtime.daemon.daemon import Daemon
from percept.runtime.daemon.gaze import Gaze
from percept.runtime.daemon.settings import DaemonOptions
from percept.runtime.demo import demo_gaze
from percept.runtime.games.language.live import GuessingGames
from percept.runtime.games.looking import SEEN_FRAMES, Looker
from percept.runtime.games.pointing import Located, PointingGames
from percept.runtime.net.link import Link
from percept.runtime.net.messages import Boxes, PointingRequest, Signal, encode
from percept.runtime.net.settings import PeerSettings
from percept.runtime.settings.experiment import load_experiment
from percept.runtime.settings.profile import PlatformProfile, load_profile
from percept.runtime.settings.scene import find_scene
from tests.support.daemon import ROOT, experiment_copy
from tests.support.polling import wait_for
from tests.support.poses import Pose, relative, seen_from
from tests.support.zenoh_rig import experiment

pytestmark = pytest.mark.timeout(120)

OP3 = ROOT / "config" / "robots" / "robotis-op3.toml"

# The robots and objects of bench/scenes/pointing-spread.toml (world frame): the red block lies
# 3 degrees off a's heading and 36 off b's, out of b's view while b looks ahead.
A: Pose = (-0.72, 0.0, 0.0)
B: Pose = (0.24625, -0.67658, 1.91986)
RED = (0.419, -0.059)
BLUE = (0.065, 0.181)  # in both robots' view from the start


@dataclass
class Robot:
    """One robot: its head (emulated servos, bus, gaze) and its stand-in perception."""

    name: str
    pose: Pose
    profile: PlatformProfile
    emu: ServoEmulator
    bus: DynamixelBus
    gaze: Gaze
    progress: tuple[int, float] = (0, -math.inf)  # frames finished, when the last was taken
    known: dict[str, Located] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def world(self) -> list[Located]:
        with self.lock:
            return list(self.known.values())

    def perceive(self, objects: dict[str, tuple[float, float]]) -> None:
        """One frame: the objects in the camera's view are seen, the others remembered."""
        taken = time.monotonic()
        sample = self.bus.latest()
        if sample is None:
            return
        camera = self.gaze.tree.camera_pose(sample.angles)
        half_w, half_h = (a / 2 for a in self.profile.camera.lens.opening_angles)
        with self.lock:
            for name, point in objects.items():
                x, y = seen_from(self.pose, *point)
                d = camera.R.T @ (np.array([x, y, 0.0]) - camera.t)
                inside = d[0] > 0 and abs(math.atan2(d[1], d[0])) < half_w
                inside = inside and abs(math.atan2(d[2], d[0])) < half_h
                if inside:
                    self.known[name] = Located(f"{self.name}-{name}", x, y)
                elif name in self.known:
                    self.known[name] = replace(self.known[name], visible=False)
            self.progress = (self.progress[0] + 1, taken)

    def sees(self, name: str) -> bool:
        with self.lock:
            return name in self.known and self.known[name].visible


@pytest.fixture
def robots() -> Iterator[dict[str, Robot]]:
    profile = load_profile("robotis-op3")
    settings = GazeSettings(enabled=True, max_speed=2.0, watchdog=0.5)
    tree = KinematicTree.from_settings(profile.kinematics)
    made: dict[str, Robot] = {}
    stop = threading.Event()
    objects = {"red": RED, "blue": BLUE}

    def perception() -> None:
        while not stop.wait(1 / 30):
            for robot in made.values():
                robot.perceive(objects)

    thread = threading.Thread(target=perception, daemon=True)
    try:
        for name, pose in (("a", A), ("b", B)):
            emu = ServoEmulator.for_profile(profile.joints, profile.bus.protocol).start()
            emu.set_angle("head_tilt", -0.5)  # looking down at the table
            bus_settings = replace(profile.bus, port=emu.port_path, timeout=0.1, stale_after=1.0)
            bus = DynamixelBus(bus_settings, profile.joints, gaze=settings)
            gaze = Gaze(bus, tree, profile.joints, settings)
            made[name] = Robot(name, pose, profile, emu, bus, gaze)
            bus.start()
        assert wait_for(lambda: all(r.bus.latest() is not None for r in made.values()), 10)
        thread.start()
        yield made
    finally:
        stop.set()
        for robot in made.values():
            robot.bus.stop()
            robot.emu.stop()


def _goals_sent(robot: Robot, goals: dict[str, float]) -> bool:
    """Whether the emulated servos were given ``goals`` (each within a tick) at some point."""
    joints = {j.name: j for j in robot.profile.joints}
    return all(
        any(abs(t - radians_to_ticks(g, joints[n])) <= 1 for t in robot.emu.goals(joints[n].id))
        for n, g in goals.items()
    )


def _games(robots: list[Robot], links: list[Link], looks: bool) -> dict[str, PointingGames]:
    """Each robot's pointing games over its link, knowing the other's pose exactly; with
    ``looks``, the robots turn their heads."""
    settings = PeerSettings(pointing_gate=0.05, answer_timeout=10.0)
    games = {}
    for robot, link, other in zip(robots, links, robots[::-1], strict=True):
        pose = relative(robot.pose, other.pose)
        games[robot.name] = PointingGames(
            link, robot.world, lambda _, p=pose: p, settings, random.Random(1)
        )
        if looks:
            games[robot.name].looker = Looker(robot.gaze, lambda r=robot: r.progress)
    # Each session sees the other (its liveliness token) and is heard on the games' topics: the
    # first pointing then goes to the other robot, not into a session still connecting.
    for link in links:
        link.watch_alive(lambda *_: None)
    others = [(link, robot.name) for link, robot in zip(links, robots[::-1], strict=True)]
    assert wait_for(lambda: all(link.alive(other) for link, other in others), 30.0)
    topics = ("pointing", "signal")
    assert wait_for(lambda: all(link.listened(t) for link in links for t in topics))
    return games


def test_the_hearer_finds_the_topic_after_turning(robots: dict[str, Robot]) -> None:
    """a points at the red block, which b has never seen (out of its view); b turns its head
    there, sees it, chooses it and the game is won; both heads look back afterwards."""
    a, b = robots["a"], robots["b"]
    assert wait_for(lambda: a.sees("red") and a.sees("blue") and b.sees("blue"), 10)
    assert "red" not in {o.id.split("-")[1] for o in b.world()}  # never seen by b
    home = {n: b.bus.latest().angles[n] for n in b.gaze.limits}  # type: ignore[union-attr]
    exp = experiment("a", "b")
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b:
        games = _games([a, b], [link_a, link_b], looks=True)
        result = games["a"].play("b", objects=["a-red"])
        assert result.outcome == "success", result
        assert wait_for(lambda: len(games["b"].results) == 1)
        heard = games["b"].results[0]
        assert heard.outcome == "success" and heard.chosen == "b-red", heard
    # b turned its head to the red block (the goals that face it were sent), a looked at it
    # before pointing; b's head is back where it was.
    for robot in (a, b):
        red = (*seen_from(robot.pose, *RED), 0.0)
        assert _goals_sent(robot, robot.gaze.aim(red)), robot.name
    assert wait_for(lambda: b.gaze.settled(), 10)
    back = b.bus.latest().angles  # type: ignore[union-attr]
    assert all(abs(back[n] - home[n]) < math.radians(0.5) for n in home), (back, home)
    assert "red" in {o.id.split("-")[1] for o in b.world()}  # now known to b


def test_without_a_looker_the_hearer_answers_from_where_it_looks(robots: dict[str, Robot]) -> None:
    """Gaze off (no looker): nothing moves, and b, which never saw the red block, finds no
    object where a points."""
    a, b = robots["a"], robots["b"]
    assert wait_for(lambda: a.sees("red") and b.sees("blue"), 10)
    exp = experiment("a", "b")
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b:
        games = _games([a, b], [link_a, link_b], looks=False)
        result = games["a"].play("b", objects=["a-red"])
    assert result.outcome == "failure" and result.reason == "the hearer found no object there"
    assert not any(r.emu.goals(j.id) for r in (a, b) for j in r.profile.joints)


def test_the_demo_moves_the_heads_of_scenes_that_look_around(tmp_path: Path) -> None:
    """``percept demo`` turns gaze on for a scene whose heads move (``tabletop-look``) unless
    told not to, and ``percept run --enable-gaze`` enables the experiment's ``[gaze]``."""
    look, basic = (load(Scene, find_scene(n)) for n in ("tabletop-look", "tabletop-basic"))
    assert demo_gaze(look, None) and not demo_gaze(basic, None)
    assert not demo_gaze(look, False) and demo_gaze(basic, True)
    experiment = experiment_copy(tmp_path)
    assert not load_experiment(experiment).gaze.enabled
    options = DaemonOptions("a", OP3, experiment, sim_scene=str(find_scene("tabletop-look")))
    assert not Daemon(options).experiment.gaze.enabled
    enabled = Daemon(replace(options, enable_gaze=True)).experiment.gaze
    assert enabled == replace(load_experiment(experiment).gaze, enabled=True)


def test_a_place_the_hearer_cannot_face_fails_with_the_reason(robots: dict[str, Robot]) -> None:
    """a points at an object behind b: b's head cannot turn there, nothing of b moves, b
    answers from what it knows (nothing there) and says why it did not look."""
    a, b = robots["a"], robots["b"]
    behind = (0.45, -1.2)  # 179 degrees off b's heading, 46 degrees right of a's
    home = {n: b.bus.latest().angles[n] for n in b.gaze.limits}  # type: ignore[union-attr]
    a.gaze.look_at(*seen_from(a.pose, *behind))  # a turns to it first: it sees it
    assert wait_for(lambda: a.gaze.settled(), 10)
    a.perceive({"far": behind})
    assert a.sees("far")
    exp = experiment("a", "b")
    with Link(exp, "a") as link_a, Link(exp, "b") as link_b:
        games = _games([a, b], [link_a, link_b], looks=True)
        result = games["a"].play("b", objects=["a-far"])
        assert result.outcome == "failure" and result.reason == "the hearer found no object there"
        assert wait_for(lambda: len(games["b"].results) == 1)
    reason = games["b"].results[0].reason
    assert reason.startswith("no object near the pointed place (the look there was given up:")
    assert "outside the head's range" in reason
    # b's head stayed where it was (looking back there is all it was told).
    for joint in b.profile.joints:
        here = radians_to_ticks(home[joint.name], joint)
        assert all(abs(t - here) <= 1 for t in b.emu.goals(joint.id)), joint.name


def test_a_look_counts_only_frames_taken_after_the_head_settled(robots: dict[str, Robot]) -> None:
    """Perception on a busy machine finishes each frame half a second after it was taken: the
    look at the red block (out of b's view: the head turns) ends only once it has finished
    frames taken after the head settled, however many older frames it finished meanwhile."""
    b = robots["b"]
    lag = 0.5
    finished = itertools.count(1)
    settled: list[float] = []  # when the looker first asked for frames: the head had settled

    def frames() -> tuple[int, float]:
        now = time.monotonic()
        if not settled:
            assert b.gaze.settled()
            settled.append(now)
        return next(finished), now - lag

    look = Looker(b.gaze, frames).look(*seen_from(B, *RED))
    assert look.seen, look
    assert time.monotonic() - settled[0] >= lag


def test_a_look_back_stopped_by_a_fault_is_tried_again(robots: dict[str, Robot]) -> None:
    """A servo that stops answering for a moment (a late reply on a busy machine) stops gaze
    as the head turns back after a game: tried once, the head stayed aside until the next game
    (for a whole demo run when none came). It is tried again once the servo answers."""
    b = robots["b"]
    pan = b.profile.joint("head_pan")

    def read_pan() -> float:  # a reading of the pan (a stale one is left out of a sample)
        assert wait_for(lambda: "head_pan" in b.bus.latest().angles, 5.0)
        return b.bus.latest().angles["head_pan"]

    home = read_pan()
    looker = Looker(b.gaze, lambda: (b.progress[0], time.monotonic()))
    # (a look itself may be given up on a loaded machine: the emulator starved)
    assert any(looker.look(*seen_from(B, *RED)).seen for _ in range(3))
    assert abs(read_pan() - home) > 0.1  # it turned
    b.emu.mute(pan.id)  # stale after 1 s: gaze stops, the look back with it
    answers = threading.Timer(1.5, b.emu.mute, (pan.id, False))
    answers.start()
    try:
        looker.back()
        assert b.gaze.settled(), b.gaze.status()
        assert abs(read_pan() - home) < 0.01
    finally:
        answers.cancel()
        b.emu.mute(pan.id, False)


def test_a_look_stopped_by_a_fault_is_tried_again(robots: dict[str, Robot]) -> None:
    """A servo that stops answering for a moment as the head turns to look stops gaze: the look
    is tried again once it answers, and the place is seen."""
    b = robots["b"]
    pan = b.profile.joint("head_pan")
    looker = Looker(b.gaze, lambda: (b.progress[0], time.monotonic()))
    b.emu.mute(pan.id)  # stale after 1 s: gaze stops on its way to the look
    answers = threading.Timer(1.5, b.emu.mute, (pan.id, False))
    answers.start()
    try:
        look = looker.look(*seen_from(B, *RED))
        assert look.seen, look
        assert b.gaze.settled(), b.gaze.status()
    finally:
        answers.cancel()
        b.emu.mute(pan.id, False)
        looker.back()


def test_watching_waits_a_few_frames_at_most(robots: dict[str, Robot]) -> None:
    """After a look a game waits for what it looked at for SEEN_FRAMES frames at most: seen in
    the third frame from now, it is found; never seen, the wait ends after those frames."""
    finished = itertools.count(1)
    looker = Looker(robots["a"].gaze, lambda: (next(finished), time.monotonic()))
    calls = itertools.count()
    assert looker.watch(lambda: next(calls) >= 3)
    polls = itertools.count()
    assert not looker.watch(lambda: next(polls) < 0)
    assert next(polls) == SEEN_FRAMES + 1  # now, then after each of the frames


def _head_goals(robot: Robot) -> int:
    """How many goal positions the head's servos were given so far."""
    return sum(
        len(robot.emu.goals(j.id)) for j in robot.profile.joints if j.name.startswith("head")
    )


def test_no_head_motion_from_a_stranger_or_from_another_robots_key(
    robots: dict[str, Robot],
) -> None:
    """Gaze on, robot a's pointing games turn its head, its players are a and b. A start signal
    from a made-up sender mallory (pointing or guessing, naming a as speaker and b as hearer),
    pointing requests from mallory, and messages forged on keys that are not their sender's
    (mallory's key saying it is b, a's own key saying it is b) give no goal to a's servos and no
    game; each is ignored or rejected and counted. Then the monitor's start turns the head: the
    goals would have shown a stranger's look."""
    a = robots["a"]
    exp = experiment("a", "b")
    settings = PeerSettings(pointing_gate=0.05, answer_timeout=1.0)
    pose = relative(A, B)
    with Link(exp, "a") as link_a, Link(exp, "mallory", listen=[]) as mallory:
        games = PointingGames(link_a, a.world, lambda _: pose, settings, players=("a", "b"))
        games.looker = Looker(a.gaze, lambda: a.progress)
        guessing = GuessingGames(link_a, list, lambda _: pose, settings, players=("a", "b"))
        boxes: list[object] = []
        link_a.subscribe("boxes", boxes.append)
        assert wait_for(lambda: a.sees("red"), 10.0)
        # Zenoh drops a put that no subscriber is known for yet: each forged topic must be heard.
        assert wait_for(lambda: all(mallory.listened(t) for t in ("signal", "pointing", "boxes")))

        def start(sender: str, play: str = "pointing") -> bytes:
            signal = Signal(f"{sender}-{play}", sender, "a", "start", "a", "b", play)
            return encode(signal)

        forged = {
            "percept/mallory/signal": [start("mallory"), start("mallory", "guessing"), start("b")],
            "percept/mallory/pointing": [
                encode(PointingRequest("m1", "mallory", "a", *RED)),
                encode(PointingRequest("m2", "b", "a", *RED)),
            ],
            "percept/a/pointing": [encode(PointingRequest("m3", "b", "a", *RED))],
            "percept/a/signal": [start("b")],
            "percept/a/boxes": [encode(Boxes("b", time.time(), ()))],
        }
        goals = _head_goals(a)
        for key, payloads in forged.items():
            for payload in payloads:
                # blocking: Zenoh's default drops a put on a congested queue, and each is counted
                mallory.session.put(key, payload, congestion_control=CongestionControl.BLOCK)
        assert wait_for(lambda: link_a.rejected == 5, 5.0), link_a.rejected_by_key
        assert wait_for(lambda: games.ignored["mallory"] == 2, 5.0), games.ignored
        assert wait_for(lambda: guessing.ignored["mallory"] == 1, 5.0), guessing.ignored
        time.sleep(1.5)  # a look or a game, had one begun, would show by now
        assert _head_goals(a) == goals
        assert games.played == guessing.played == 0 and not boxes
        monitor = Link(exp, "monitor", listen=[])
        try:
            assert wait_for(lambda: monitor.listened("signal"))
            monitor.publish("signal", Signal("m-1", "monitor", "a", "start", "a", "b"))
            assert wait_for(lambda: _head_goals(a) > goals, 10.0)
        finally:
            monitor.close()


def test_network_gaze_lab_lets_games_turn_the_head_only_in_the_lab(
    robots: dict[str, Robot], tmp_path: Path
) -> None:
    """``[peers] network_gaze = "lab"``: in peer mode the games get no looker (they are played
    without turning the head) and the status says so and why; in the lab deployment (client mode
    over mutual TLS) they do. The default, ``any``, lets them everywhere."""
    experiment = experiment_copy(tmp_path, ('network_gaze = "any"', 'network_gaze = "lab"'))
    options = DaemonOptions("a", OP3, experiment, sim_scene=str(find_scene("tabletop-basic")))
    daemon = Daemon(options)
    exp = load_experiment(experiment)
    with Link(exp, "a", listen=[]) as link:
        daemon.gaze, daemon.link = robots["a"].gaze, link
        daemon.games = PointingGames(link, robots["a"].world, lambda _: None)
        daemon._let_games_look()
        status = daemon._network_status()
        assert daemon.games.looker is None and status["games_look"] is False
        assert str(status["trust"]).startswith("peer mode: any process that reaches")
        lab = replace(exp.network, mode="client", connect=("tls/127.0.0.1:7447",))
        daemon.experiment = replace(exp, network=replace(lab, certificates=tmp_path))
        daemon._let_games_look()
        assert daemon.games.looker is not None and daemon._network_status()["games_look"]
        assert str(daemon._network_status()["trust"]).startswith("lab: mutual TLS")
        daemon.experiment = replace(exp, peers=replace(exp.peers, network_gaze="any"))
        daemon.games.looker = None
        daemon._let_games_look()
        assert daemon.games.looker is not None
