"""Game contexts from scene records: the objects two robots attend to together.

A context is one scene seen by a speaker and a hearer: the objects both see, row by row the same
object, each with the speaker's and the hearer's own scaled features and their names for it (the
naming game's individuals). From perception (``perceived``) the rows are found as a hearer finds
what it is pointed at (SPEC §4.7): each of the speaker's objects is mapped into the hearer's frame
through the hearer's estimate of the speaker's pose, and the hearer's nearest object within
``gate`` metres is the same one (objects that two map to are left out). From the truth
(``truth``) the rows are the true objects both robots have in view, with their true features.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from percept.perception.features.experience import FEATURES
from percept.runtime.games.language.dataset.records import RobotView, SceneRecord, to_mine

#: Channels that do not depend on where a robot stands: the default for the guessing game (x
#: and y are egocentric: one robot's left is not the other's).
SHARED_CHANNELS = ("width", "height", "luminance", "green_red", "yellow_blue")
GATE = 0.05  # metres, as the experiment's pointing gate
MIN_VISIBLE = 0.5  # the truth counts an object as seen when this much of it shows


@dataclass(frozen=True)
class Context:
    """One scene for one speaker-hearer pair; row ``i`` is the same object for both."""

    scene: int
    speaker: str
    hearer: str
    speaker_values: np.ndarray
    hearer_values: np.ndarray
    speaker_names: tuple[str, ...]
    hearer_names: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.speaker_names)


def contexts(
    scenes: Iterable[SceneRecord],
    source: str = "perceived",
    channels: Sequence[str] = SHARED_CHANNELS,
    gate: float = GATE,
    least: int = 1,
) -> list[Context]:
    """Both directions (a speaks to b, b to a) of every scene, with at least ``least`` shared
    objects; ``source`` ``perceived`` or ``truth``."""
    if source not in ("perceived", "truth"):
        raise ValueError(f"unknown source of features {source!r}: perceived or truth")
    unknown = sorted(set(channels) - set(FEATURES))
    if unknown:
        raise ValueError(f"unknown channel(s) {', '.join(unknown)}; known: {', '.join(FEATURES)}")
    out = []
    for scene in scenes:
        for speaker, hearer in (scene.robots, scene.robots[::-1]):
            pair = _perceived if source == "perceived" else _true
            rows = pair(speaker, hearer, channels, gate)
            if len(rows) >= least:
                s_vals, h_vals, s_names, h_names = zip(*rows, strict=True)
                out.append(
                    Context(
                        scene.index,
                        speaker.robot,
                        hearer.robot,
                        np.array(s_vals, dtype=float),
                        np.array(h_vals, dtype=float),
                        s_names,
                        h_names,
                    )
                )
    return out


Row = tuple[list[float], list[float], str, str]


def _vector(scaled: dict[str, float | None], channels: Sequence[str]) -> list[float]:
    return [math.nan if (v := scaled.get(c)) is None else float(v) for c in channels]


def _perceived(
    speaker: RobotView, hearer: RobotView, channels: Sequence[str], gate: float
) -> list[Row]:
    if hearer.peer is None:
        return []
    labels = {o.id: o.label for o in (*speaker.truth, *hearer.truth)}
    mine = [o for o in hearer.objects if o.features.get("x") is not None]
    if not mine:
        return []
    where = np.array([[o.features["x"], o.features["y"]] for o in mine], dtype=float)
    chosen: dict[int, list[int]] = {}
    for i, o in enumerate(speaker.objects):
        fx, fy = o.features.get("x"), o.features.get("y")
        if fx is None or fy is None:
            continue
        point = np.array(to_mine(hearer.peer, fx, fy))
        d = np.linalg.norm(where - point, axis=1)
        if d.min() <= gate:
            chosen.setdefault(int(d.argmin()), []).append(i)
    rows = []
    for j, (i,) in ((j, found) for j, found in chosen.items() if len(found) == 1):
        a, b = speaker.objects[i], mine[j]
        rows.append(
            (
                _vector(a.scaled, channels),
                _vector(b.scaled, channels),
                _name(a.truth, labels, speaker.robot, a.id),
                _name(b.truth, labels, hearer.robot, b.id),
            )
        )
    return rows


def _name(truth: int | None, labels: dict[int, str], robot: str, anchor: str) -> str:
    """The individual an anchor is: its true object's label; an anchor of nothing real is an
    individual of its own."""
    return labels[truth] if truth is not None else f"{robot}:{anchor}"


def _true(speaker: RobotView, hearer: RobotView, channels: Sequence[str], gate: float) -> list[Row]:
    theirs = {o.id: o for o in hearer.truth if o.visible >= MIN_VISIBLE}
    rows = []
    for o in speaker.truth:
        other = theirs.get(o.id)
        if o.visible >= MIN_VISIBLE and other is not None:
            rows.append(
                (_vector(o.scaled, channels), _vector(other.scaled, channels), o.label, o.label)
            )
    return rows
