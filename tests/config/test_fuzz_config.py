"""Property-based tests of the config loader: no input fails with anything but ConfigError.

Three kinds of input: arbitrary TOML-like data (nested tables, lists and every TOML scalar type),
the shipped files with one part replaced, removed or added, and arbitrary bytes in a file.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from percept.config.loader import ConfigError, build, load
from percept.drivers.sim.scenarios.distribution import Distribution
from percept.runtime.settings.experiment import Experiment
from percept.runtime.settings.profile import PlatformProfile
from tests.support.fuzz import fuzz_settings, mutate, paths, tables, values

REPO = Path(__file__).resolve().parents[2]
FILES = {
    PlatformProfile: sorted((REPO / "config" / "robots").glob("*.toml")),
    Experiment: sorted((REPO / "config" / "experiments").glob("*.toml")),
    Distribution: sorted((REPO / "config" / "scenarios").glob("*.toml")),
}
FUZZ = fuzz_settings(150)
# 150 builds of a whole experiment per test: a few seconds, a minute and a half on a machine
# loaded eightfold; the suite's 120 s per test would make a fuzz test fail on load alone.
pytestmark = pytest.mark.timeout(600)


def _build(cls: type, data: Any) -> None:
    try:
        result = build(cls, data, REPO / "config" / "fuzz.toml")
    except ConfigError as err:
        assert str(err).startswith(str(REPO / "config" / "fuzz.toml"))
    else:
        assert isinstance(result, cls)


@pytest.mark.parametrize("cls", [PlatformProfile, Experiment])
@FUZZ
@given(data=tables)
def test_arbitrary_tables(cls: type, data: dict[str, Any]) -> None:
    _build(cls, data)


MUTATION_TARGETS = [(cls, path) for cls, paths in FILES.items() for path in paths]


@pytest.mark.parametrize(
    ("cls", "file"), MUTATION_TARGETS, ids=[p.name for _, p in MUTATION_TARGETS]
)
@FUZZ
@given(data=st.data())
def test_shipped_files_with_one_part_changed(cls: type, file: Path, data: st.DataObject) -> None:
    doc = tomllib.loads(file.read_text(encoding="utf-8"))
    path = data.draw(st.sampled_from(paths(doc)))
    action = data.draw(st.sampled_from(["replace", "remove", "add"]))
    _build(cls, mutate(doc, path, action, data.draw(values)))


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz") / "fuzz.toml"


@pytest.mark.parametrize("cls", [PlatformProfile, Experiment])
@FUZZ
@given(
    content=st.one_of(
        st.binary(max_size=200),
        st.text(max_size=200).map(str.encode),
        st.sampled_from(
            [
                b"name = 1\n",
                b"[kinematics]\n",
                b"robots = [{}]\n",
                b"\xff = 1",
                b"name = " + b"1" * 5000,
                b"name = 0x" + b"f" * 4000,
                b'name = "x"\n[[robots]]\nname = "a"\nprofile = "~nobody-here/p.toml"\n',
            ]
        ),
    )
)
def test_arbitrary_file_content(cls: type, content: bytes, scratch: Path) -> None:
    scratch.write_bytes(content)
    try:
        load(cls, scratch)
    except ConfigError as err:
        assert str(err).startswith(str(scratch))


def _op3_with_ticks(ticks: int) -> dict[str, Any]:
    doc = tomllib.loads(
        (REPO / "config" / "robots" / "robotis-op3.toml").read_text(encoding="utf-8")
    )
    doc["joints"][0]["ticks_per_rev"] = ticks
    return doc


def _tabletop_with_profile(profile: str) -> dict[str, Any]:
    doc = tomllib.loads(
        (REPO / "config" / "experiments" / "tabletop.toml").read_text(encoding="utf-8")
    )
    doc["robots"][0]["profile"] = profile
    return doc


@pytest.mark.parametrize(
    ("cls", "doc", "start"),
    [
        (PlatformProfile, _op3_with_ticks(2**1100), "joints[0].ticks_per_rev: expected a number"),
        (PlatformProfile, {"name": 16**4400}, "name: expected a string, got an integer too long"),
        (
            Experiment,
            _tabletop_with_profile("~nobody-here/p.toml"),
            'robots[0].profile: cannot expand "~nobody-here/p.toml": no such user',
        ),
    ],
    ids=["int-beyond-float", "int-beyond-str", "unknown-home"],
)
def test_regressions_found_by_fuzzing(cls: type, doc: dict[str, Any], start: str) -> None:
    with pytest.raises(ConfigError) as info:
        build(cls, doc, "fuzz.toml")
    assert str(info.value).startswith(f"fuzz.toml: {start}")


@pytest.mark.parametrize(
    "content", [b"\x80", b"name = " + b"1" * 5000], ids=["not-utf8", "int-too-long-to-parse"]
)
def test_unreadable_toml_is_a_config_error(content: bytes, scratch: Path) -> None:
    scratch.write_bytes(content)
    with pytest.raises(ConfigError) as info:
        load(PlatformProfile, scratch)
    assert str(info.value).startswith(f"{scratch}: invalid TOML: ")
