"""Property-based tests of the config loader: no input fails with anything but ConfigError.

Three kinds of input: arbitrary TOML-like data (nested tables, lists and every TOML scalar type),
the shipped files with one part replaced, removed or added, and arbitrary bytes in a file.
"""

from __future__ import annotations

import copy
import dataclasses
import tomllib
import typing
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from percept.config.loader import ConfigError, build, load
from percept.runtime.settings.experiment import Experiment
from percept.runtime.settings.profile import PlatformProfile

REPO = Path(__file__).resolve().parents[2]
FILES = {
    PlatformProfile: sorted((REPO / "config" / "robots").glob("*.toml")),
    Experiment: sorted((REPO / "config" / "experiments").glob("*.toml")),
}
FUZZ = settings(max_examples=150, deadline=None, database=None)


def _field_names(cls: type, seen: set[str]) -> set[str]:
    """Every key name a file of ``cls`` can hold, so that generated tables hit real fields."""
    for f in dataclasses.fields(cls):
        seen.add(f.name)
        tp = typing.get_type_hints(cls)[f.name]
        for inner in (tp, *typing.get_args(tp)):
            if dataclasses.is_dataclass(inner) and inner.__name__ not in seen:
                seen.add(inner.__name__)
                _field_names(inner, seen)
    return seen


KEYS = sorted(_field_names(PlatformProfile, set()) | _field_names(Experiment, set()))

scalars = st.one_of(
    st.booleans(),
    st.integers(),
    st.integers(min_value=-(2**64), max_value=2**64),
    # Beyond the largest float; beyond str()'s 4300 digits (built lazily: hypothesis reprs samples).
    st.tuples(st.sampled_from([1100, 17600]), st.sampled_from([1, -1])).map(lambda t: t[1] << t[0]),
    st.floats(),
    st.text(max_size=16),
    st.sampled_from(["", "~", "~nobody-here/x.toml", "a", "XM430-W350", "tcp/127.0.0.1:7447"]),
    st.datetimes(),
    st.dates(),
    st.times(),
)
keys = st.one_of(st.sampled_from(KEYS), st.text(max_size=8))
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(keys, inner, max_size=5)),
    max_leaves=24,
)
tables = st.dictionaries(keys, values, max_size=8)


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


def _paths(node: Any, path: tuple = ()) -> list[tuple]:
    """Every place in a TOML document: the keys of its tables and the indices of its lists."""
    children = node.items() if isinstance(node, dict) else enumerate(node)
    found = []
    for key, child in children:
        found.append((*path, key))
        if isinstance(child, dict | list):
            found.extend(_paths(child, (*path, key)))
    return found


def _mutate(doc: dict[str, Any], path: tuple, action: str, value: Any) -> dict[str, Any]:
    doc = copy.deepcopy(doc)
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    last = path[-1]
    if action == "replace":
        parent[last] = value
    elif action == "remove":
        del parent[last]
    elif isinstance(parent, dict):
        parent[f"unknown_{last}"] = value
    else:
        parent.insert(last, value)
    return doc


MUTATION_TARGETS = [(cls, path) for cls, paths in FILES.items() for path in paths]


@pytest.mark.parametrize(
    ("cls", "file"), MUTATION_TARGETS, ids=[p.name for _, p in MUTATION_TARGETS]
)
@FUZZ
@given(data=st.data())
def test_shipped_files_with_one_part_changed(cls: type, file: Path, data: st.DataObject) -> None:
    doc = tomllib.loads(file.read_text())
    path = data.draw(st.sampled_from(_paths(doc)))
    action = data.draw(st.sampled_from(["replace", "remove", "add"]))
    _build(cls, _mutate(doc, path, action, data.draw(values)))


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
    doc = tomllib.loads((REPO / "config" / "robots" / "robotis-op3.toml").read_text())
    doc["joints"][0]["ticks_per_rev"] = ticks
    return doc


def _tabletop_with_profile(profile: str) -> dict[str, Any]:
    doc = tomllib.loads((REPO / "config" / "experiments" / "tabletop.toml").read_text())
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
