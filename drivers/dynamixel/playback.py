"""Recorded joint angles played back by the servo emulator, in step with the wall clock.

A recording is a CSV table with a header: a ``t`` column (seconds) and one column of radians
per joint, as ``percept sim`` writes ``joints.csv`` (other columns, such as ``frame``, are
ignored). Played from a wall-clock ``epoch``, the angle of a joint at wall time ``w`` is the
recording's at ``t = t0 + (w - epoch)``, ``t0`` the first row's time, linearly interpolated
between rows; before the first row the first angle holds, after the last row the last.
"""

from __future__ import annotations

import csv
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np


class RecordingError(ValueError):
    """A joint recording that cannot be played: the message names the file and the problem."""


@dataclass(frozen=True)
class JointRecording:
    """Joint angles (radians) at times ``t`` (seconds, increasing), one array per joint."""

    t: np.ndarray
    angles: dict[str, np.ndarray]

    def at(self, elapsed: float) -> dict[str, float]:
        """Each joint's angle ``elapsed`` seconds after the first row."""
        t = self.t[0] + elapsed
        return {name: float(np.interp(t, self.t, values)) for name, values in self.angles.items()}

    @property
    def duration(self) -> float:
        """Seconds from the first row to the last."""
        return float(self.t[-1] - self.t[0])


def read_recording(path: str | Path, joints: Iterable[str]) -> JointRecording:
    """The columns of ``joints`` that ``path`` holds (at least one), with its ``t`` column."""
    known = list(joints)
    try:
        with Path(path).open(newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except OSError as err:
        raise RecordingError(f"{path}: cannot read: {err.strerror or err}") from None
    if not rows:
        raise RecordingError(f"{path}: no rows (expected a header with t and joint columns)")
    columns = list(rows[0])
    played = [j for j in known if j in columns]
    if "t" not in columns or not played:
        raise RecordingError(
            f"{path}: expected a t column and at least one joint column of {', '.join(known)}; "
            f"it has {', '.join(columns)}"
        )
    try:
        table = np.array([[float(r["t"]), *(float(r[j]) for j in played)] for r in rows])
    except (TypeError, ValueError) as err:
        raise RecordingError(f"{path}: not a number: {err}") from None
    if not np.isfinite(table).all():
        raise RecordingError(f"{path}: holds a value that is not finite")
    if np.any(np.diff(table[:, 0]) <= 0):
        raise RecordingError(f"{path}: the times in column t must increase from row to row")
    return JointRecording(table[:, 0], {j: table[:, 1 + k] for k, j in enumerate(played)})
