"""Perception parameters for the offline commands: a preset or file, then ``--set`` overrides.

``--params chapter`` reads ``config/presets/perception-chapter.toml``; ``--params FILE`` reads a
file holding a perception table (a preset, or an experiment file's ``[perception]`` table when
the file has one); ``--set split.enabled=false`` changes one key (the value is TOML).
"""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING

from percept.config import find
from percept.config.loader import ConfigError, TomlValue, build, read_toml

if TYPE_CHECKING:
    from percept.perception.params import PerceptionParams


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--params",
        metavar="PRESET|TOML",
        help="perception parameters: a preset name (chapter) or a TOML file (default: defaults)",
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one parameter, e.g. --set split.enabled=false (repeatable)",
    )


def add_calibration_arguments(p: argparse.ArgumentParser) -> None:
    """Where the background model comes from: the first N frames or a saved calibration."""
    calibration = p.add_mutually_exclusive_group()
    calibration.add_argument(
        "--calibration-frames",
        type=int,
        metavar="N",
        help="learn the background from the first N frames (default: background."
        "calibration_frames of the parameters, 30)",
    )
    calibration.add_argument(
        "--background", type=Path, metavar="NPZ", help="use a saved background calibration"
    )


def _preset_path(name: str) -> Path:
    path = Path(name)
    if path.suffix == ".toml" or path.exists():
        return path
    return find("presets", f"perception-{name}")


def _override(data: dict[str, TomlValue], assignment: str) -> None:
    key, sep, raw = assignment.partition("=")
    if not sep or not key.strip():
        raise ConfigError("--set", assignment, "expected KEY=VALUE, e.g. anchors.alpha=0.2")
    try:
        value: TomlValue = tomllib.loads(f"v = {raw.strip()}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):
        value = raw.strip()  # a bare word is a string
    *tables, last = key.strip().split(".")
    node = data
    for name in tables:
        inner = node.setdefault(name, {})
        if not isinstance(inner, dict):
            raise ConfigError("--set", key, f"{name} is not a table")
        node = inner
    node[last] = value


def params_from_args(args: argparse.Namespace) -> PerceptionParams:
    """The parameters that ``--params`` and ``--set`` describe."""
    from percept.perception.params import PerceptionParams

    data: dict[str, TomlValue] = {}
    source: str | Path = "--set"
    key = ""
    if args.params:
        source = _preset_path(args.params)
        data = read_toml(source)
        perception = data.get("perception")
        if isinstance(perception, dict):
            data, key = perception, "perception"
    for assignment in args.overrides:
        _override(data, assignment)
    return build(PerceptionParams, data, source, key)
