"""Config loading: every error names the file, the key path and what was expected."""

from __future__ import annotations

from pathlib import Path

import pytest

from percept.config.loader import ConfigError
from percept.runtime.cli import main
from percept.runtime.settings.experiment import load_experiment
from percept.runtime.settings.profile import load_profile

REPO = Path(__file__).resolve().parents[2]
OP3 = REPO / "config" / "robots" / "robotis-op3.toml"


def _profile_with(tmp_path: Path, old: str, new: str) -> Path:
    text = OP3.read_text(encoding="utf-8")
    assert old in text, old
    path = tmp_path / "op3.toml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


def _error(path: Path) -> str:
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    return str(info.value)


@pytest.mark.parametrize("profile", sorted((REPO / "config" / "robots").glob("*.toml")))
def test_shipped_profiles_load(profile: Path) -> None:
    p = load_profile(profile)
    assert p.joints, "a profile without joints cannot point its camera"
    assert p.kinematics.camera_link


@pytest.mark.parametrize("experiment", sorted((REPO / "config" / "experiments").glob("*.toml")))
def test_shipped_experiments_load(experiment: Path) -> None:
    e = load_experiment(experiment)
    for robot in e.robots:
        load_profile(robot.profile)


def test_op3_values() -> None:
    p = load_profile(OP3)
    assert (p.joint("head_pan").id, p.joint("head_tilt").id) == (19, 20)
    assert p.bus.protocol == 2.0
    assert p.joints[0].ticks_per_rev == 4096.0


def test_wrong_type_names_file_key_and_expectation(tmp_path: Path) -> None:
    path = _profile_with(tmp_path, "id = 20", 'id = "x"')
    assert _error(path) == f'{path}: joints[1].id: expected an integer 0-252, got "x"'


def test_out_of_range(tmp_path: Path) -> None:
    path = _profile_with(tmp_path, "id = 19", "id = 300")
    assert _error(path) == f"{path}: joints[0].id: expected an integer 0-252, got 300"


def test_missing_key(tmp_path: Path) -> None:
    path = _profile_with(tmp_path, 'name = "head_tilt"\n', "")
    assert _error(path) == f"{path}: joints[1].name: missing; expected a string"


def test_unknown_key(tmp_path: Path) -> None:
    path = _profile_with(tmp_path, "baudrate = 1000000", "baudrat = 1000000")
    msg = _error(path)
    assert msg.startswith(f"{path}: bus.baudrat: unknown key; expected one of: port, baudrate,")


def test_literal_choice(tmp_path: Path) -> None:
    path = _profile_with(tmp_path, "protocol = 2.0", "protocol = 3.0")
    assert _error(path) == f"{path}: bus.protocol: expected one of 1.0, 2.0, got 3.0"


def test_tuple_length(tmp_path: Path) -> None:
    path = _profile_with(tmp_path, "opening_angles = [1.0123, 0.6708]", "opening_angles = [1.0]")
    assert (
        _error(path)
        == f"{path}: camera.lens.opening_angles: expected a list of 2 numbers 0.01-3.1, got a list"
    )


def test_cross_field_rule(tmp_path: Path) -> None:
    path = _profile_with(tmp_path, "id = 20", "id = 19")
    assert _error(path) == f"{path}: (top level): duplicate servo id: 19"


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.toml"
    assert _error(path) == f"{path}: file not found"


def test_bad_toml(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("name = \n", encoding="utf-8")
    assert _error(path).startswith(f"{path}: invalid TOML")


def test_cli_exits_2_on_bad_config(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _profile_with(tmp_path, "id = 20", 'id = "x"')
    assert main(["config", "--robot", str(path)]) == 2
    assert f'{path}: joints[1].id: expected an integer 0-252, got "x"' in capsys.readouterr().err


def _experiment_with(tmp_path: Path, old: str, new: str) -> Path:
    source = REPO / "config" / "experiments" / "tabletop.toml"
    text = source.read_text(encoding="utf-8").replace('"../', f'"{source.parent.parent}/')
    assert old in text, old
    path = tmp_path / "experiment.toml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("old", "new", "error"),
    [
        (
            "stale_after = 1.0",
            'stale_after = 1.0\nplayers = ["a", "c"]',
            "peers.players[1]: 'c' is not a robot of the experiment: ['a', 'b']",
        ),
        (
            "stale_after = 1.0",
            "stale_after = 1.0\narena = 1e4",
            "peers.arena: expected a number 0.1-1000.0, got 10000.0",
        ),
        (
            'name = "b"',
            f'name = "{"b" * 65}"',
            "robots[1]: robot name '" + "b" * 65 + "': expected 1 to 64 letters, digits, - and _",
        ),
    ],
)
def test_experiment_peers_and_names(tmp_path: Path, old: str, new: str, error: str) -> None:
    path = _experiment_with(tmp_path, old, new)
    with pytest.raises(ConfigError) as info:
        load_experiment(path)
    assert str(info.value).startswith(f"{path}: {error}"), str(info.value)


def test_players_default_to_the_experiments_robots(tmp_path: Path) -> None:
    assert load_experiment(_experiment_with(tmp_path, "x", "x")).players == ("a", "b")
    path = _experiment_with(tmp_path, "stale_after = 1.0", 'stale_after = 1.0\nplayers = ["b"]')
    assert load_experiment(path).players == ("b",)
