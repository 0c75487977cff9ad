"""Language games (runtime.language): records, agreement, contexts, games and game scripts on
synthetic scenes with known features, and ``percept scenes`` / ``percept games`` end to end on a
few rendered scenes."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from percept.perception.features.experience import FEATURES
from percept.perception.features.scaling import FeatureScaling, FeatureStats
from percept.runtime.cli import main
from percept.runtime.games.language.dataset.agreement import agreement, feature_pairs
from percept.runtime.games.language.dataset.contexts import SHARED_CHANNELS, contexts
from percept.runtime.games.language.dataset.records import (
    RobotView,
    SceneFileError,
    SceneObject,
    SceneRecord,
    TrueObject,
    read_scenes,
    write_scenes,
)
from percept.runtime.games.language.guessing import GuessingGame, GuessingSettings
from percept.runtime.games.language.lexicon import Lexicon
from percept.runtime.games.language.naming import NamingGame
from percept.runtime.games.language.population import play
from percept.runtime.games.language.script import (
    Event,
    GuessingHearer,
    GuessingSpeaker,
    LocalChannel,
    PeerPose2,
    Thing,
)
from percept.runtime.record.scorecard import relative_pose, to_robot

POSES = {"a": (-0.8, 0.0, 0.0), "b": (0.1, -0.8, 1.7)}
# Scaled x, y: [0.3, 1.3] and [-0.5, 0.5] metres onto 0..1 (the objects are ~0.8 m away).
SCALING = FeatureScaling({f: FeatureStats(0.8 if f == "x" else 0.0, 0.25) for f in FEATURES})


def _catalogue(rng: np.random.Generator, n: int = 10) -> list[np.ndarray]:
    """Items with well-spread shared features (width, height, colour), in 0..1."""
    return [rng.uniform(0.05, 0.95, len(SHARED_CHANNELS)) for _ in range(n)]


def synthetic_scenes(
    count: int, seed: int = 0, noise: float = 0.01, items: int = 10
) -> list[SceneRecord]:
    """Scenes of 2-5 catalogue items both robots see, each robot's features the item's plus
    Gaussian noise, positions in each robot's frame, exact peer poses."""
    rng = np.random.default_rng(seed)
    catalogue = _catalogue(rng, items)
    scenes = []
    for k in range(count):
        n = int(rng.integers(2, 6))
        picks = rng.choice(len(catalogue), n, replace=False)
        places: list[np.ndarray] = []
        while len(places) < n:
            p = rng.uniform(-0.25, 0.25, 2)
            if all(np.linalg.norm(p - q) > 0.12 for q in places):
                places.append(p)
        views = []
        for name, other in (("a", "b"), ("b", "a")):
            objects, truth = [], []
            for i, (item, place) in enumerate(zip(picks, places, strict=True)):
                x, y = to_robot(POSES[name], *place)
                shared = catalogue[item] + rng.normal(0, noise, len(SHARED_CHANNELS))
                raw = {"x": x, "y": y, **dict(zip(SHARED_CHANNELS, shared, strict=True))}
                scaled = {f: SCALING.stats[f].scale(raw[f]) if f in "xy" else raw[f] for f in raw}
                objects.append(SceneObject(f"o{i + 1}", raw, scaled, True, int(item) + 1))
                true = {"x": x, "y": y, **dict(zip(SHARED_CHANNELS, catalogue[item], strict=True))}
                truth.append(TrueObject(int(item) + 1, f"item-{item}", true, true, 1.0))
            peer = relative_pose(POSES[name], POSES[other])
            views.append(RobotView(name, tuple(objects), peer, peer, tuple(truth)))
        scenes.append(SceneRecord(k, seed, (views[0], views[1])))
    return scenes


# -- records --------------------------------------------------------------------------------------


def test_a_scenes_file_round_trips(tmp_path: Path) -> None:
    scenes = synthetic_scenes(5)
    # Off-ground objects have no position, and a robot may have no pose of its peer.
    a, b = scenes[0].robots
    blind = SceneObject("o9", dict.fromkeys(FEATURES), dict.fromkeys(FEATURES), False, None)
    scenes[0] = SceneRecord(
        0, 0, (RobotView("a", (*a.objects, blind), None, a.true_peer, a.truth), b)
    )
    path = tmp_path / "scenes.jsonl"
    assert write_scenes(path, scenes) == 5
    assert list(read_scenes(path)) == scenes


def test_a_malformed_scene_line_is_named(tmp_path: Path) -> None:
    path = tmp_path / "scenes.jsonl"
    write_scenes(path, synthetic_scenes(2))
    with path.open("a", encoding="utf-8") as fh:
        fh.write('{"index": 3, "robots": []}\n')
    with pytest.raises(SceneFileError, match=r"scenes.jsonl:3"):
        list(read_scenes(path))


# -- agreement and contexts -----------------------------------------------------------------------


def test_agreement_measures_the_difference_and_correlation() -> None:
    exact = agreement(feature_pairs(synthetic_scenes(20, noise=0.0), SCALING))
    for f in FEATURES:
        assert exact[f].n > 40
        assert exact[f].d == pytest.approx(0.0, abs=1e-9)
        assert exact[f].r == pytest.approx(1.0)
    noisy = agreement(feature_pairs(synthetic_scenes(20, noise=0.05), SCALING))
    # |N(0, .05) - N(0, .05)| has mean 0.05 * 2 / sqrt(pi)
    for f in SHARED_CHANNELS:
        assert noisy[f].d == pytest.approx(0.05 * 2 / math.sqrt(math.pi), rel=0.25)
        assert 0.9 < noisy[f].r < 0.99
    # positions: robot b's x, y go through a's (exact) pose of b
    assert noisy["x"].d < 1e-9 and noisy["y"].d < 1e-9


def test_contexts_pair_objects_through_the_peer_pose() -> None:
    scenes = synthetic_scenes(10)
    found = contexts(scenes, "perceived")
    assert len(found) == 20  # both directions of every scene
    assert all(c.speaker_names == c.hearer_names for c in found)
    assert sum(map(len, found)) == 2 * sum(len(s.robots[0].objects) for s in scenes)
    # A wrong peer pose matches nothing within the gate.
    a, b = scenes[0].robots
    x, y, theta = b.peer
    off = RobotView("b", b.objects, (x + 0.3, y, theta), b.true_peer, b.truth)
    assert [c.speaker for c in contexts([SceneRecord(0, 0, (a, off))], "perceived")] == ["b"]
    truth = contexts(scenes, "truth")
    assert [len(c) for c in truth] == [len(c) for c in found]


# -- games ----------------------------------------------------------------------------------------


def test_the_naming_game_converges() -> None:
    found = contexts(synthetic_scenes(60), "perceived")
    agents, history = play(NamingGame(), found, 10, 3000, seed=1)
    assert history.success_over(500) >= 0.95
    assert history.success_over(500, 500) < 0.6  # it had to learn
    assert history.coherence[-1] >= 0.9
    assert 10 <= np.mean([len(a.lexicon) for a in agents]) <= 12  # about a word per item


@pytest.mark.parametrize("kind", ["prototypes", "trees"])
def test_the_guessing_game_converges(kind: str) -> None:
    found = contexts(synthetic_scenes(60), "perceived", least=2)
    game = GuessingGame(len(SHARED_CHANNELS), GuessingSettings(categories=kind))
    agents, history = play(game, found, 10, 8000, seed=2)
    assert history.success_over(1000) >= 0.9
    assert history.success_over(1000, 1000) < 0.6
    assert all(a.categories is not None and len(a.categories) > 3 for a in agents)


def test_a_seed_repeats_a_run_exactly() -> None:
    found = contexts(synthetic_scenes(30), "perceived", least=2)
    game = GuessingGame(len(SHARED_CHANNELS))
    runs = [play(game, found, 5, 1500, seed=s)[1] for s in (7, 7, 8)]
    assert runs[0].outcomes == runs[1].outcomes
    assert runs[0].lexicon == runs[1].lexicon and runs[0].coherence == runs[1].coherence
    assert runs[0].outcomes != runs[2].outcomes


def test_bad_game_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="prototypes or trees"):
        GuessingGame(5, GuessingSettings(categories="clusters"))
    with pytest.raises(ValueError, match="perceived or truth"):
        contexts(synthetic_scenes(1), "imagined")
    with pytest.raises(ValueError, match="unknown channel"):
        contexts(synthetic_scenes(1), "perceived", ("colour",))
    with pytest.raises(ValueError, match="two agents"):
        play(NamingGame(), contexts(synthetic_scenes(1), "perceived"), 1, 10, 0)


# -- game scripts ---------------------------------------------------------------------------------


def _things(view: RobotView) -> list[Thing]:
    return [
        Thing(o.id, o.features["x"], o.features["y"], tuple(o.scaled[c] for c in SHARED_CHANNELS))
        for o in view.objects
    ]


def test_guessing_game_scripts_learn_over_messages() -> None:
    """Two agents play the guessing game as scripts, over messages and pointing alone."""
    rules = GuessingGame(len(SHARED_CHANNELS))
    agents = {name: rules.new_agent(i) for i, name in enumerate("ab")}
    rng = np.random.default_rng(3)
    scenes = synthetic_scenes(40, seed=3)
    results = []
    for k in range(1500):
        scene = scenes[k % len(scenes)]
        views = {v.robot: v for v in scene.robots}
        me, peer = ("a", "b") if k % 2 else ("b", "a")
        channel = LocalChannel()

        def pose(of: str, views: dict[str, RobotView] = views):
            return lambda: PeerPose2(*views[of].peer)

        speaker = GuessingSpeaker(
            f"g{k}", me, peer, channel.send, rules, agents[me],
            lambda v=views[me]: _things(v), pose(me), 0.05, rng=rng,
        )  # fmt: skip
        hearer = GuessingHearer(
            f"g{k}", peer, me, channel.send, rules, agents[peer],
            lambda v=views[peer]: _things(v), pose(peer), 0.05,
        )  # fmt: skip
        channel.run(speaker, hearer)
        assert speaker.done
        if speaker.reason:  # it found nothing to say: the hearer heard nothing
            assert hearer.state == "ready"
        else:
            assert hearer.done and hearer.success == speaker.success
        results.append(bool(speaker.success))
    assert np.mean(results[-300:]) >= 0.9 > np.mean(results[:100])
    # A message in the wrong state or for another game changes nothing.
    hearer.handle(Event("utterance", {"game": hearer.game, "word": "x"}))
    assert hearer.ignored == 1 and hearer.done
    speaker.handle(Event("guess", {"game": "another", "x": 0.0, "y": 0.0}))
    assert speaker.ignored == 1


# -- commands -------------------------------------------------------------------------------------


def test_percept_scenes_and_games_write_their_files(tmp_path: Path, capsys) -> None:
    out = tmp_path / "scenes"
    assert main(["scenes", "--count", "2", "--seed", "4", "--out", str(out)]) == 0
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert line["scenes"] == 2
    scenes = list(read_scenes(out / "scenes.jsonl"))
    assert [s.index for s in scenes] == [0, 1]
    for scene in scenes:
        assert {r.robot for r in scene.robots} == {"a", "b"}
        for view in scene.robots:
            assert 2 <= len(view.truth) <= 5
            assert view.peer is not None  # the robots found each other through the boxes
            assert math.dist(view.peer[:2], view.true_peer[:2]) < 0.1
            matched = [o for o in view.objects if o.truth is not None]
            assert matched, "the pipeline anchored some of the objects"
            truth = {t.id: t for t in view.truth}
            for o in matched:  # anchors are where their true objects are
                t = truth[o.truth]
                gap = math.dist(
                    (o.features["x"], o.features["y"]), (t.features["x"], t.features["y"])
                )
                assert gap < 0.1
    table = json.loads((out / "agreement.json").read_text(encoding="utf-8"))
    assert set(table) == set(FEATURES)
    assert all(set(v) == {"d", "r", "n"} for v in table.values())
    assert table["green_red"]["n"] > 0 and table["green_red"]["d"] < 0.1
    assert (out / "agreement.png").stat().st_size > 1000
    games = tmp_path / "games"
    argv = ["games", str(out), "--game", "guessing", "--agents", "4", "--games", "300"]
    assert main([*argv, "--out", str(games)]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in ("success_last_1000", "lexicon_size", "coherence", "categories"):
        assert key in summary
    assert summary["games"] == 300 and summary["contexts"] >= 1
    assert (games / "success.png").stat().st_size > 1000
    assert (
        json.loads((games / "summary.json").read_text(encoding="utf-8"))["curves"]["games"][-1]
        == 300
    )


def test_percept_games_without_scenes_is_a_config_error(tmp_path: Path, capsys) -> None:
    assert main(["games", str(tmp_path), "--game", "naming", "--out", str(tmp_path / "o")]) == 2
    assert "scenes.jsonl" in capsys.readouterr().err


def test_a_bounded_lexicon_pushes_out_its_weakest_word_form() -> None:
    """A player making up a word per game cannot grow the lexicon past its bound: each new word
    form pushes out the one whose best association is the weakest, the oldest of equals, with
    every association of it; the words the games rewarded stay."""
    lexicon: Lexicon[str] = Lexicon(most=3)
    lexicon.add("bado", "red")
    lexicon.succeeded("bado", "red")  # 0.6: the strongest
    lexicon.add("kilo", "blue")
    lexicon.add("kilo", "green")
    for i in range(100):
        lexicon.add(f"made{i:03d}", "red")
    assert len(lexicon) == 3
    assert list(lexicon.words()) == ["bado", "made098", "made099"]
    assert lexicon.best_word("red") == ("bado", 0.6)
    assert lexicon.best_word("blue") is None and lexicon.meanings("kilo") == []


def test_an_agent_makes_no_categories_past_its_bound() -> None:
    rules = GuessingGame(2, GuessingSettings(most_categories=4))
    agent = rules.new_agent(0)
    rng = np.random.default_rng(3)
    for _ in range(200):
        agent.grow(rng.uniform(0, 1, (4, 2)), 0)
    assert agent.categories is not None and 4 <= len(agent.categories) < 4 + 4
