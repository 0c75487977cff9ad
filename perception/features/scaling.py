"""Scaling features to [0, 1] (chapter 5.2.3, SPEC §4.5).

With the mean ``mu`` and standard deviation ``sigma`` of a feature over many objects, a value is
mapped linearly from ``[mu - 2 sigma, mu + 2 sigma]`` onto ``[0, 1]`` and clipped. The statistics
come from recordings or simulated runs (``percept stats``), live in a small TOML file or in the
experiment's ``[scaling]`` table, and are shared by all robots of an experiment, so that the same
object gives both robots nearly the same scaled features.

The statistics file (written by ``percept stats``, read by :meth:`FeatureScaling.load`) has one
table per feature::

    [x]
    mean = 0.92
    sigma = 0.31
    n = 1200
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from percept.perception.features.experience import FEATURES, SensoryExperience


@dataclass(frozen=True)
class FeatureStats:
    """Mean and standard deviation of one feature over ``n`` objects (``n`` 0: not measured)."""

    mean: float = field(metadata={"min": -1e6, "max": 1e6, "doc": "mean of the feature"})
    sigma: float = field(metadata={"min": 1e-9, "max": 1e6, "doc": "standard deviation, > 0"})
    n: int = field(
        default=0, metadata={"min": 0, "max": 1_000_000_000, "doc": "objects behind the estimate"}
    )

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mean) and math.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(f"need a finite mean and a positive sigma, got {self}")

    def scale(self, value: float) -> float:
        """``value`` mapped from [mean - 2 sigma, mean + 2 sigma] onto [0, 1], clipped."""
        return min(1.0, max(0.0, (value - self.mean) / (4.0 * self.sigma) + 0.5))


#: Table-top defaults for a robot about 0.3-2 m from toys of 3-30 cm, used until measured.
DEFAULT_STATS: dict[str, FeatureStats] = {
    "x": FeatureStats(1.0, 0.4),
    "y": FeatureStats(0.0, 0.4),
    "width": FeatureStats(0.1, 0.05),
    "height": FeatureStats(0.1, 0.05),
    "luminance": FeatureStats(128.0, 40.0),
    "green_red": FeatureStats(128.0, 20.0),
    "yellow_blue": FeatureStats(128.0, 20.0),
}


@dataclass(frozen=True)
class ScalingSettings:
    """The experiment's ``[scaling]`` table: a statistics file from ``percept stats`` and/or
    inline per-feature statistics (``[scaling.features.x] mean = .., sigma = ..``), which win
    over the file; features given in neither use :data:`DEFAULT_STATS`."""

    file: Path | None = field(
        default=None, metadata={"doc": "statistics file written by percept stats"}
    )
    features: dict[str, FeatureStats] = field(
        default_factory=dict, metadata={"doc": "per-feature mean and sigma, overriding the file"}
    )

    def __post_init__(self) -> None:
        unknown = sorted(set(self.features) - set(FEATURES))
        if unknown:
            raise ValueError(f"unknown feature(s) {', '.join(unknown)}; known: {FEATURES}")
        if self.file is not None:
            FeatureScaling.load(self.file)  # a missing or broken file is a config error now


class FeatureScaling:
    """Per-feature statistics and the scaling they define; one per experiment."""

    def __init__(self, stats: Mapping[str, FeatureStats]) -> None:
        missing = [name for name in FEATURES if name not in stats]
        if missing:
            raise ValueError(f"no statistics for feature(s) {', '.join(missing)}")
        self.stats = {name: stats[name] for name in FEATURES}

    @classmethod
    def from_settings(cls, settings: ScalingSettings) -> FeatureScaling:
        """Defaults, overridden by the settings' file, overridden by its inline features."""
        stats = dict(DEFAULT_STATS)
        if settings.file is not None:
            stats.update(cls.load(settings.file).stats)
        stats.update(settings.features)
        return cls(stats)

    @classmethod
    def load(cls, path: str | Path) -> FeatureScaling:
        """Read a statistics file; features it lacks keep their defaults. Raises ValueError."""
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError) as err:
            raise ValueError(f"{path}: cannot read feature statistics: {err}") from None
        stats = dict(DEFAULT_STATS)
        for name, table in data.items():
            if name not in FEATURES or not isinstance(table, dict):
                raise ValueError(f"{path}: {name}: expected a table named after a feature")
            try:
                stats[name] = FeatureStats(
                    mean=float(table["mean"]),
                    sigma=float(table["sigma"]),
                    n=int(table.get("n", 0)),
                )
            except (KeyError, TypeError, ValueError) as err:
                raise ValueError(
                    f"{path}: {name}: needs numbers mean and sigma > 0 ({err})"
                ) from None
        return cls(stats)

    def save(self, path: str | Path, comment: str = "") -> None:
        """Write the statistics file (TOML, one table per feature)."""
        lines = [f"# {line}" for line in comment.splitlines()]
        for name, s in self.stats.items():
            lines += ["", f"[{name}]", f"mean = {s.mean!r}", f"sigma = {s.sigma!r}", f"n = {s.n}"]
        Path(path).write_text("\n".join(lines).lstrip("\n") + "\n", encoding="utf-8")

    def scale(self, experience: SensoryExperience) -> dict[str, float | None]:
        """Scaled features in [0, 1] by name; None where the feature is unknown (off the
        ground)."""
        out: dict[str, float | None] = {}
        for name, value in experience.features().items():
            out[name] = None if value is None else self.stats[name].scale(value)
        return out

    @classmethod
    def measure(cls, samples: Iterable[Mapping[str, float | None]]) -> FeatureScaling:
        """Statistics of feature dicts (None values skipped). Raises ValueError when a feature
        has fewer than two values or no spread."""
        columns: dict[str, list[float]] = {name: [] for name in FEATURES}
        for sample in samples:
            for name in FEATURES:
                value = sample.get(name)
                if value is not None and math.isfinite(value):
                    columns[name].append(float(value))
        stats = {}
        for name, values in columns.items():
            if len(values) < 2:
                raise ValueError(f"feature {name}: {len(values)} value(s); need at least two")
            sigma = float(np.std(values, ddof=1))
            if sigma <= 1e-9:
                raise ValueError(f"feature {name}: no spread over {len(values)} objects")
            stats[name] = FeatureStats(float(np.mean(values)), sigma, len(values))
        return cls(stats)
