"""Scenes drawn from a distribution (``percept scenarios``): the same seed gives the same files,
the shipped distribution covers every factor it promises, every scene loads, and a bad
distribution file is reported by file and key."""

from __future__ import annotations

import colorsys
import json
import math
from collections import Counter
from pathlib import Path

import pytest

from percept.config import find
from percept.config.loader import ConfigError, build, load
from percept.config.writer import dumps
from percept.drivers.sim.scenarios.distribution import Distribution
from percept.drivers.sim.scenarios.draw import draw_scene
from percept.drivers.sim.scene import Scene
from percept.runtime.cli import main

pytestmark = pytest.mark.timeout(300)

SHIPPED = find("scenarios", "default")
PROFILES = {"a": "robotis-op3", "b": "robotis-op3"}


def drawn(count: int = 200) -> list[Scene]:
    dist = load(Distribution, SHIPPED)
    return [
        build(Scene, draw_scene(dist, seed, PROFILES).data, SHIPPED.parent / "x.toml")
        for seed in range(1, count + 1)
    ]


def test_the_same_seed_writes_the_same_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    assert main(["scenarios", "--count", "3", "--seed", "7", "--out", str(tmp_path / "a")]) == 0
    assert main(["scenarios", "--count", "2", "--seed", "8", "--out", str(tmp_path / "b")]) == 0
    written = json.loads(capsys.readouterr().out.splitlines()[0])["scenes"]
    assert written == ["room-0007.toml", "room-0008.toml", "room-0009.toml"]
    for name in ("room-0008.toml", "room-0009.toml"):  # a scene is the same in any batch
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert (tmp_path / "a" / "room-0007.toml").read_bytes() != (
        tmp_path / "a" / "room-0008.toml"
    ).read_bytes()


def test_every_written_scene_loads_with_its_profiles(tmp_path: Path) -> None:
    from percept.runtime.settings.scene import load_scene

    assert main(["scenarios", "--count", "5", "--seed", "1", "--out", str(tmp_path)]) == 0
    for file in sorted(tmp_path.glob("*.toml")):
        scene, platforms = load_scene(file)
        assert set(platforms) == {"a", "b"} and scene.calibration > 0


def test_two_hundred_scenes_cover_every_factor() -> None:
    scenes = drawn(200)
    objects = [[o for o in s.objects if not o.is_figure] for s in scenes]
    counts = Counter(len(o) for o in objects)
    assert min(counts) == 3 and max(counts) == 10
    assert {o.shape for os in objects for o in os} == {
        "block",
        "cuboid",
        "cylinder",
        "cone",
        "ball",
        "toy",
    }
    extents = [e for os in objects for o in os for e in o.size]
    assert min(extents) >= 0.03 and max(extents) <= 0.15
    assert min(extents) < 0.035 and max(extents) > 0.145

    def hsv(c: tuple[int, int, int]) -> tuple[float, float, float]:
        return colorsys.rgb_to_hsv(*(v / 255 for v in c))

    colours = [o.color for os in objects for o in os]
    assert any(hsv(c)[2] < 0.25 for c in colours)  # dark
    assert any(hsv(c)[1] < 0.15 and hsv(c)[2] > 0.3 for c in colours)  # desaturated
    floor_like = [
        any(max(abs(a - b) for a, b in zip(o.color, s.floor.color, strict=True)) <= 14 for o in os)
        for s, os in zip(scenes, objects, strict=True)
    ]
    assert sum(floor_like) >= 10
    shared = [len({o.color for o in os}) < len(os) for os in objects]
    assert sum(shared) >= 20

    actions = Counter(e.action for s in scenes for e in s.timeline)
    for action in ("add", "remove", "move", "lay_down", "in_front", "exposure", "white_balance"):
        assert actions[action] >= 10, action
    lights = [e for s in scenes for e in s.timeline if e.action == "lights"]
    assert any(e.lamp is not None for e in lights)  # one of two lamps alone
    assert any(
        e.span == 0 and e.lamp is None and e.scale is not None and e.scale < 0.8 for e in lights
    )  # switched
    drifts = [e for e in lights if e.lamp is None and e.span > 0]
    assert min(e.span for e in drifts) < 20 and max(e.span for e in drifts) > 100
    assert max(1 - e.scale for e in drifts if e.scale is not None) > 0.5
    assert {len(s.lighting.lights) for s in scenes} == {1, 2}
    assert sum(s.camera.flicker > 0 for s in scenes) >= 40

    heads = [r.joints.get("head_pan") for s in scenes for r in s.robots]
    assert sum(h is None for h in heads) >= 80  # still heads
    moving = [h for h in heads if h is not None]
    assert len(moving) >= 200
    for h in moving:  # a moving head calibrates while it sweeps its range over the empty floor
        lo, hi = h.bounds()
        assert lo <= -0.9 and hi >= 0.9

    people = [[o for o in s.objects if o.is_figure] for s in scenes]
    arms = [o for ps in people for o in ps if o.size[0] < 0.1]
    assert len(arms) >= 40
    at_start = [any(o.present for o in ps) for ps in people]
    assert sum(at_start) >= 30  # present while the background calibrates
    standing = 0
    for s in scenes:
        moves: dict[int, list[float]] = {}
        for e in sorted(s.timeline, key=lambda e: e.t):
            if e.action == "move" and e.object is not None and e.object > 100:
                moves.setdefault(e.object, []).append(e.t)
        standing += any(len(ts) == 2 and ts[1] - ts[0] >= 6.5 for ts in moves.values())
    assert standing >= 30  # walked up, stood 5-20 s, walked off

    assert {s.camera.jpeg_quality for s in scenes} >= {0}
    qualities = [s.camera.jpeg_quality for s in scenes if s.camera.jpeg_quality]
    assert min(qualities) <= 62 and max(qualities) >= 93
    assert all(s.camera.noise > 0 and s.camera.shutter > 0 for s in scenes)

    box_distances = [math.hypot(*b.pose[:2]) for s in scenes for b in s.boxes]
    assert all(len(s.boxes) == 2 for s in scenes)
    assert min(box_distances) < 0.45 and max(box_distances) > 0.7
    durations = [s.duration for s in scenes]
    assert min(durations) >= 20 and max(durations) <= 60


@pytest.mark.parametrize(
    ("change", "key", "problem"),
    [
        ("[objects]\ncount = [5, 3]\n", "objects", "count: the low end 5 is above"),
        ("[objects]\ncolour = [1, 2, 3]\n", "objects.colour", "unknown key"),
        ("[light]\np_drift = 1.5\n", "light.p_drift", "0"),
        ('[objects]\nshapes = ["block", "star"]\n', "objects.shapes", "star"),
    ],
)
def test_a_bad_distribution_names_file_and_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: str, key: str, problem: str
) -> None:
    text = 'name = "lab"\n[[robots]]\nname = "a"\nprofile = "robotis-op3"\n' + change
    bad = tmp_path / "lab.toml"
    bad.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        load(Distribution, bad)
    assert err.value.file == str(bad)
    assert err.value.key.startswith(key)
    assert problem in str(err.value)
    args = ["scenarios", "--count", "1", "--seed", "1", "--out", str(tmp_path / "out")]
    assert main([*args, "--distribution", str(bad)]) == 2  # the command says the same
    assert f"{bad}: {key}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_toml_writer_round_trips_a_scene() -> None:
    import tomllib

    dist = load(Distribution, SHIPPED)
    data = draw_scene(dist, 3, PROFILES).data
    assert tomllib.loads(dumps(data, "a header")) == data


def test_a_profile_path_of_the_distribution_resolves_from_the_output_folder(
    tmp_path: Path,
) -> None:
    from percept.runtime.settings.scene import load_scene

    lab = tmp_path / "lab"
    (lab / "robots").mkdir(parents=True)
    own = (find("robots", "robotis-op3")).read_text(encoding="utf-8")
    (lab / "robots" / "our-op3.toml").write_text(own, encoding="utf-8")
    dist = lab / "room.toml"
    dist.write_text(
        'name = "ours"\n[[robots]]\nname = "a"\nprofile = "robots/our-op3.toml"\n',
        encoding="utf-8",
    )
    out = tmp_path / "elsewhere" / "scenes"
    assert (
        main(
            [
                "scenarios",
                "--count",
                "1",
                "--seed",
                "2",
                "--out",
                str(out),
                "--distribution",
                str(dist),
            ]
        )
        == 0
    )
    text = (out / "ours-0002.toml").read_text(encoding="utf-8")
    assert 'profile = "../../lab/robots/our-op3.toml"' in text
    scene, platforms = load_scene(out / "ours-0002.toml")
    assert scene.robots[0].profile.resolve() == (lab / "robots" / "our-op3.toml").resolve()
    assert set(platforms) == {"a"}
