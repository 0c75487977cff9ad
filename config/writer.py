"""TOML text from plain data, for the files percept writes (generated scenes).

The subset the shipped files use: strings, integers, floats, booleans, arrays of them (nested),
tables and arrays of tables. A table's plain keys come first, then its sub-tables, then its
arrays of tables, as TOML requires. Floats keep their shortest round-tripping text, so a file
read back gives exactly the values written.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence

from percept.config.loader import TomlValue

_BARE_KEY = set("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")


def dumps(data: Mapping[str, TomlValue], header: str = "") -> str:
    """The TOML text of ``data``; ``header`` (lines of text) goes first as comments."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    _table(data, [], lines)
    return "\n".join(lines).strip("\n") + "\n"


def _key(name: str) -> str:
    return name if name and set(name) <= _BARE_KEY else json.dumps(name)


def _is_table_array(value: TomlValue) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _value(value: TomlValue) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"TOML has no {value}")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, dict):
        inner = ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items())
        return "{ " + inner + " }" if inner else "{}"
    if isinstance(value, Sequence):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def _table(data: Mapping[str, TomlValue], path: list[str], lines: list[str]) -> None:
    tables = {k: v for k, v in data.items() if isinstance(v, dict)}
    arrays = {k: v for k, v in data.items() if _is_table_array(v)}
    for k, v in data.items():
        if k not in tables and k not in arrays:
            lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in tables.items():
        assert isinstance(v, dict)
        if not v or any(not isinstance(x, dict) and not _is_table_array(x) for x in v.values()):
            lines += ["", "[" + ".".join(_key(p) for p in [*path, k]) + "]"]
        _table(v, [*path, k], lines)
    for k, v in arrays.items():
        assert isinstance(v, list)
        for item in v:
            assert isinstance(item, dict)
            lines += ["", "[[" + ".".join(_key(p) for p in [*path, k]) + "]]"]
            _table(item, [*path, k], lines)
