"""Generated TOML-like documents for the property-based tests of every file and message parser:
arbitrary nested data whose keys are mostly the real field names of profiles and experiments, and
the places of a document (:func:`paths`) to change one at a time (:func:`mutate`)."""

from __future__ import annotations

import copy
import dataclasses
import typing
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from percept.runtime.settings.experiment import Experiment
from percept.runtime.settings.profile import PlatformProfile


def field_names(cls: type, seen: set[str]) -> set[str]:
    """Every key name a file of ``cls`` can hold, so that generated tables hit real fields."""
    for f in dataclasses.fields(cls):
        seen.add(f.name)
        tp = typing.get_type_hints(cls)[f.name]
        for inner in (tp, *typing.get_args(tp)):
            if dataclasses.is_dataclass(inner) and inner.__name__ not in seen:
                seen.add(inner.__name__)
                field_names(inner, seen)
    return seen


def fuzz_settings(examples: int) -> settings:
    """Settings of the property-based tests: ``examples`` new inputs a run (no database: every
    run draws its own), no deadline and no complaint about slow generation: on a loaded CI
    machine the time of an example says nothing about the parser."""
    return settings(
        max_examples=examples,
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow],
    )


KEYS = sorted(field_names(PlatformProfile, set()) | field_names(Experiment, set()))

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


def paths(node: Any, path: tuple = ()) -> list[tuple]:
    """Every place in a TOML document: the keys of its tables and the indices of its lists."""
    children = node.items() if isinstance(node, dict) else enumerate(node)
    found = []
    for key, child in children:
        found.append((*path, key))
        if isinstance(child, dict | list):
            found.extend(paths(child, (*path, key)))
    return found


def mutate(doc: dict[str, Any], path: tuple, action: str, value: Any) -> dict[str, Any]:
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
