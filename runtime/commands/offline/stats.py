"""``percept stats``: each feature's mean and standard deviation over the objects in recordings or
simulated runs, written as the statistics file that scales features for an experiment.

Accepted sources (any mix):

- ``.mcap`` recordings of the daemon: the ``percept.world`` messages on ``/percept/world``,
  as far as the file is intact (a killed daemon's file, a damaged chunk skipped),
- JSON-lines files (``.jsonl``, ``.ndjson``, ``.json``: one JSON value per line), where a line is
  a world message (``{"objects": [{"features": {...}}, ...]}``), one object
  (``{"features": {...}}``), a flat feature dict (``{"x": .., "width": .., ...}``), or any of these
  wrapped as ``{"payload": ...}``.

Features that are null (an object off the ground has no x, y, width, height) are skipped, feature
by feature. Each object in each message counts once: a long recording of few objects weighs them
by how long they were seen, so record varied scenes. Objects remembered out of sight
(``"visible": false``) are not seen and do not count.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from percept.runtime.net.codec import JSON

NAME = "stats"
HELP = "compute feature means and deviations over recorded or simulated objects (for scaling)"

log = logging.getLogger("percept.stats")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("sources", nargs="+", metavar="SOURCE", help=".mcap or JSON-lines files")
    p.add_argument("--out", required=True, metavar="FILE", help="statistics file to write (TOML)")


def feature_dicts(value: JSON) -> Iterator[Mapping[str, JSON]]:
    """The feature dicts inside one decoded JSON value (see the module doc)."""
    from percept.perception.features.experience import FEATURES

    if isinstance(value, list):
        for item in value:
            yield from feature_dicts(item)
    elif isinstance(value, Mapping):
        payload, objects, features = (value.get(k) for k in ("payload", "objects", "features"))
        if isinstance(payload, Mapping | list):
            yield from feature_dicts(payload)
        elif isinstance(objects, list):
            yield from feature_dicts(objects)
        elif isinstance(features, Mapping):
            if value.get("visible") is not False:
                yield features
        elif any(name in value for name in FEATURES):
            yield value


class SourceError(Exception):
    """A source that cannot be read: missing, not JSON lines, not an MCAP recording."""


def _json_lines(path: Path) -> Iterator[JSON]:
    with path.open(
        encoding="utf-8", errors="replace"
    ) as fh:  # a binary file fails as "not JSON", not UTF-8
        for number, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                yield json.loads(line)
            except json.JSONDecodeError as err:
                raise SourceError(f"{path}:{number}: not JSON: {err.msg}") from None


def _mcap_messages(path: Path) -> Iterator[JSON]:
    """The world models of a recording, as far as it is intact (a killed daemon's file has no
    summary; a damaged chunk is skipped:
    :func:`percept.runtime.record.reader.read_recording`)."""
    from percept.runtime.record.reader import RecordingError, read_recording

    try:
        for kind, item in read_recording(path):
            if kind == "world":
                yield item
    except RecordingError as err:
        raise SourceError(str(err)) from None


def samples(paths: list[Path]) -> Iterator[Mapping[str, float | None]]:
    """Feature dicts of every object in every source; a feature that is neither a number nor
    null is a :class:`SourceError`."""
    for path in paths:
        if not path.is_file():
            raise SourceError(f"{path}: no such file")
        values = _mcap_messages(path) if path.suffix == ".mcap" else _json_lines(path)
        count = 0
        for value in values:
            for features in feature_dicts(value):
                count += 1
                yield _numbers(path, features)
        log.info("%s: %d objects", path, count)


def _numbers(path: Path, features: Mapping[str, JSON]) -> dict[str, float | None]:
    """The features statistics are made of, each a number or null."""
    from percept.perception.features.experience import FEATURES

    out: dict[str, float | None] = {}
    for name in FEATURES:
        value = features.get(name)
        if value is not None and not isinstance(value, int | float):
            raise SourceError(f"{path}: feature {name} is {value!r}, not a number")
        out[name] = value
    return out


def run(args: argparse.Namespace) -> int:
    from percept.perception.features.scaling import FeatureScaling

    paths = [Path(s) for s in args.sources]
    try:
        scaling = FeatureScaling.measure(samples(paths))
    except SourceError as err:
        print(f"percept stats: {err}", file=sys.stderr)
        return 2
    except ValueError as err:  # too few values, no spread
        print(f"percept stats: {err}", file=sys.stderr)
        return 1
    n = max(s.n for s in scaling.stats.values())
    comment = (
        f"Feature statistics from {n} objects, written by percept stats from:\n"
        + "\n".join(f"  {p}" for p in paths)
        + '\nName this file in the experiment\'s [scaling] table: file = "..."'
    )
    scaling.save(args.out, comment)
    for name, s in scaling.stats.items():
        print(f"{name:12} mean {s.mean:10.4f}  sigma {s.sigma:9.4f}  n {s.n}")
    print(f"-> {args.out}")
    return 0
