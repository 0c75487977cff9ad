"""Every config value is bounded by what it can do, and every bad file, path or option named in
issue 14 ends ``percept`` with exit 2 and a message naming the file and the key, never a
traceback."""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from percept.config.loader import ConfigError, build
from percept.drivers.sim.scenarios.distribution import Distribution
from percept.drivers.sim.scene import Scene
from percept.runtime.cli import main
from percept.runtime.net.router import RouterSettings
from percept.runtime.settings.experiment import Experiment
from percept.runtime.settings.profile import PlatformProfile

REPO = Path(__file__).resolve().parents[2]
EXPERIMENT = REPO / "config" / "experiments" / "tabletop.toml"
OP3 = REPO / "config" / "robots" / "robotis-op3.toml"
DAY = 86400.0


def _numbers(tp: object) -> bool:
    """Whether a value of type ``tp`` holds numbers (directly, in a tuple or optional)."""
    if tp in (int, float):
        return True
    return any(_numbers(a) for a in typing.get_args(tp) if a is not Ellipsis)


def _number_fields(cls: type, prefix: str = "", seen: set[type] | None = None):
    """(key, field) of every numeric field of ``cls`` and of the tables inside it."""
    seen = set() if seen is None else seen
    seen.add(cls)
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp, key = hints[f.name], f"{prefix}{f.name}"
        if _numbers(tp):
            yield key, f
        for inner in (tp, *typing.get_args(tp), *(typing.get_args(a) for a in typing.get_args(tp))):
            for t in inner if isinstance(inner, tuple) else (inner,):
                if dataclasses.is_dataclass(t) and t not in seen:
                    yield from _number_fields(t, f"{key}.", seen)


ROOTS = (Experiment, PlatformProfile, Scene, RouterSettings, Distribution)
ALL_NUMBERS = [(root.__name__, key, f) for root in ROOTS for key, f in _number_fields(root)]


@pytest.mark.parametrize(("root", "key", "f"), ALL_NUMBERS, ids=[k for _, k, _ in ALL_NUMBERS])
def test_every_number_has_bounds(root: str, key: str, f: dataclasses.Field) -> None:
    lo, hi = f.metadata.get("min"), f.metadata.get("max")
    assert lo is not None and hi is not None, f"{root}.{key} is unbounded"
    assert lo <= hi
    if f.metadata.get("doc", "").startswith("seconds"):
        assert hi <= DAY, f"{root}.{key}: a timeout of more than a day"


# The experiment's plain numeric keys (tables, not lists of tables): each refused above its max.
TOP = [
    (key, f)
    for key, f in _number_fields(Experiment)
    if not key.startswith(("robots.", "landmarks.boxes.", "scaling.features."))
]


def _set(data: dict, key: str, value: object) -> dict:
    node = data
    *tables, last = key.split(".")
    for name in tables:
        node = node.setdefault(name, {})
    node[last] = value
    return data


@settings(max_examples=120, deadline=None, database=None)
@given(st.sampled_from(TOP), st.floats(min_value=1.0001, max_value=1e308))
def test_beyond_max_is_refused_at_its_key(field_: tuple, factor: float) -> None:
    key, f = field_
    value: object = abs(f.metadata["max"]) * factor + 1
    if isinstance(f.default, int):
        value = int(min(value, 1e18)) + 1
    if isinstance(f.default, tuple):
        value = [value] * len(f.default)
    data = {"name": "x", "robots": [{"name": "a", "profile": str(OP3)}]}
    with pytest.raises(ConfigError) as info:
        build(Experiment, _set(data, key, value), "exp.toml")
    assert info.value.key.startswith(key), (info.value.key, key)
    assert "expected" in info.value.problem


def _experiment(tmp_path: Path, extra: str, robots: str = "") -> Path:
    path = tmp_path / "exp.toml"
    robots = robots or f'[[robots]]\nname = "a"\nprofile = "{OP3}"\n'
    path.write_text(f'name = "x"\n{extra}\n{robots}', encoding="utf-8")
    return path


def _exit(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    return err


def test_answer_timeout_of_1e308_is_refused(tmp_path: Path, capsys) -> None:
    path = _experiment(tmp_path, "[peers]\nanswer_timeout = 1e308")
    err = _exit(["config", "--experiment", str(path)], capsys)
    assert f"{path}: peers.answer_timeout: expected a number 0.01-86400.0, got 1e+308" in err


def test_calibration_memory_is_checked_before_the_daemon_starts(tmp_path: Path, capsys) -> None:
    path = _experiment(tmp_path, "[perception.background]\ncalibration_frames = 100000")
    err = _exit(["run", "--experiment", str(path), "--sim", "tabletop-basic"], capsys)
    # OP3's camera: 320x200; 100000 frames of it take 18311 MiB against the 2048 MiB budget.
    assert f"{path}: perception.background.calibration_frames: 100000 frames of 320x200" in err
    assert "need 18311 MiB" in err and "calibration_memory = 2048 MiB" in err
    assert "use at most 11184 frames" in err
    err = _exit(["config", "--robot", str(OP3), "--experiment", str(path)], capsys)
    assert "perception.background.calibration_frames" in err


def test_calibration_memory_budget_is_a_setting(tmp_path: Path, capsys) -> None:
    extra = "[perception.background]\ncalibration_frames = 100000\ncalibration_memory = 20000"
    path = _experiment(tmp_path, extra)
    assert main(["config", "--robot", str(OP3), "--experiment", str(path)]) == 0
    capsys.readouterr()


def test_calibration_refuses_frames_larger_than_configured() -> None:
    from percept.perception.params import BackgroundParams
    from percept.perception.segmentation.background import BackgroundModel, CalibrationError

    params = BackgroundParams(calibration_frames=1000, calibration_memory=1.0)
    frames = (np.zeros((480, 640, 3), np.uint8) for _ in range(2))
    with pytest.raises(CalibrationError, match="1000 frames of 640x480 need 879 MiB"):
        BackgroundModel.calibrate(frames, params)


def test_deeply_nested_toml(tmp_path: Path, capsys) -> None:
    path = tmp_path / "deep.toml"
    path.write_text("a = " + "[" * 100_000 + "]" * 100_000, encoding="utf-8")
    err = _exit(["config", "--experiment", str(path)], capsys)
    assert f"{path}: invalid TOML: nested too deeply" in err


@pytest.mark.parametrize(
    ("prefix", "words"),
    [("percept/**", "holds *: a key"), ("a?#", "holds # ?: a key"), ("a//b", "non-empty parts")],
)
def test_prefix_must_be_a_plain_key(tmp_path: Path, capsys, prefix: str, words: str) -> None:
    path = _experiment(tmp_path, f'prefix = "{prefix}"')
    err = _exit(["config", "--experiment", str(path)], capsys)
    assert f"{path}: prefix: " in err and words in err


@pytest.mark.parametrize(
    ("endpoint", "words"),
    [
        ("tcp/127.0.0.1:99999", "expected tcp/HOST:PORT with a port 0-65535"),
        ("nonsense", "expected PROTOCOL/ADDRESS"),
        ("tcp/127.0.0.1", "expected tcp/HOST:PORT"),
        ("carrier-pigeon/loft", "expected PROTOCOL/ADDRESS"),
    ],
)
def test_endpoint_is_checked(tmp_path: Path, capsys, endpoint: str, words: str) -> None:
    robots = f'[[robots]]\nname = "a"\nprofile = "{OP3}"\nendpoint = "{endpoint}"\n'
    path = _experiment(tmp_path, "", robots)
    err = _exit(["config", "--experiment", str(path)], capsys)
    assert f"{path}: robots[0].endpoint: {words}" in err
    path = _experiment(tmp_path, f'[network]\nconnect = ["{endpoint}"]')
    err = _exit(["config", "--experiment", str(path)], capsys)
    assert f"{path}: network.connect[0]: {words}" in err


def test_good_endpoints_pass(tmp_path: Path, capsys) -> None:
    path = _experiment(tmp_path, '[network]\nconnect = ["tcp/[::1]:7447", "udp/host:0"]')
    assert main(["config", "--experiment", str(path)]) == 0
    capsys.readouterr()


def _profile(tmp_path: Path, old: str, new: str) -> Path:
    text = OP3.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "robot.toml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


def test_urdf_that_is_a_folder(tmp_path: Path, capsys) -> None:
    (tmp_path / "robot.urdf").mkdir()
    path = _profile(tmp_path, "[kinematics]\n", '[kinematics]\nurdf = "robot.urdf"\n')
    err = _exit(["config", "--robot", str(path)], capsys)
    assert f"{path}: kinematics: urdf: {tmp_path / 'robot.urdf'} is a folder" in err


@pytest.mark.parametrize(
    ("name", "content", "words"),
    [
        ("cam.yml", None, "not an OpenCV YAML/XML intrinsics file"),
        ("cam.json", None, "not valid JSON"),
        ("cam.yml", b'%YAML:1.0\ncamera_matrix: "abc"\n', "not an OpenCV YAML/XML"),
        (
            "cam.json",
            b'{"camera_matrix": "abc"}',
            "camera_matrix, distortion_coefficients, image_width",
        ),
        ("cam.json", b"[1, 2]", "expected a JSON object"),
        ("cam.json", b'{"camera_matrix": [1,0,0,0,1,0,0,0,1]}', "image_width and image_height"),
    ],
)
def test_corrupt_intrinsics_refused_by_config(
    tmp_path: Path, capsys, name: str, content: bytes | None, words: str
) -> None:
    file = tmp_path / name
    file.write_bytes(content if content is not None else np.random.default_rng(1).bytes(3000))
    path = _profile(tmp_path, "[camera.lens]\n", f'[camera.lens]\nintrinsics = "{name}"\n')
    err = _exit(["config", "--robot", str(path)], capsys)
    assert f"{path}: camera.lens: {file}: {words}" in err


def _run(tmp_path: Path, *extra: str) -> list[str]:
    return ["run", "--experiment", str(EXPERIMENT), "--sim", "tabletop-basic", *extra]


def test_background_of_random_bytes(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bg.npz"
    bad.write_bytes(np.random.default_rng(2).bytes(5000))
    err = _exit(_run(tmp_path, "--background", str(bad)), capsys)
    assert f"--background: {bad}: not a background model saved by percept" in err


@pytest.mark.parametrize("option", ["--record", "--background"])
def test_output_is_a_folder_or_in_a_missing_one(tmp_path: Path, capsys, option: str) -> None:
    err = _exit(_run(tmp_path, option, str(tmp_path)), capsys)
    assert f"{option}: {tmp_path}: is a folder; expected a file name" in err
    missing = tmp_path / "nope" / "out.mcap"
    err = _exit(_run(tmp_path, option, str(missing)), capsys)
    assert f"{option}: {missing}: the folder {missing.parent} does not exist" in err
