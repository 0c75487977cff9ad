"""Perceptual agreement (SPEC §4.11, Loetzsch's thesis table 8.1): how far apart the two robots'
scaled features are for the same object.

For every true object that both robots have an anchor for (the truth tells which anchor is which
object), per feature the pair of the two robots' scaled values; ``d`` is the mean absolute
difference of the pairs and ``r`` their correlation. ``x`` and ``y`` are egocentric: robot b's
position of the object is first taken into robot a's frame through a's own estimate of b's pose
(the perspective a hearer takes when it is pointed at) and scaled like a's, so they measure the
position estimates and the peer pose together; scenes where a has no pose of b give no x, y pair.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from percept.perception.features.experience import FEATURES
from percept.perception.features.scaling import FeatureScaling
from percept.runtime.games.language.dataset.records import (
    Pose2,
    SceneObject,
    SceneRecord,
    TrueObject,
    to_mine,
)

#: An object as one robot saw it: its anchor, or (the truth) the true object.
Seen = SceneObject | TrueObject


@dataclass(frozen=True)
class Agreement:
    """One feature's agreement: mean absolute difference, correlation (None below two pairs or
    without spread), number of pairs; ``pairs`` the (a, b) values behind them."""

    d: float | None
    r: float | None
    n: int
    pairs: tuple[tuple[float, float], ...] = ()

    def to_json(self) -> dict[str, float | int | None]:
        return {"d": self.d, "r": self.r, "n": self.n}


def feature_pairs(
    scenes: Iterable[SceneRecord], scaling: FeatureScaling, source: str = "perceived"
) -> dict[str, list[tuple[float, float]]]:
    """Per feature the (robot a, robot b) scaled values of every object both robots see:
    ``perceived`` by their anchors, or (``truth``) the true features of the objects both have
    in view, positions through the true pose: how much the objects themselves look different
    from the two sides."""
    pairs: dict[str, list[tuple[float, float]]] = {f: [] for f in FEATURES}
    for scene in scenes:
        a, b = scene.robots
        seen: list[tuple[Seen, Seen | None]]
        if source == "truth":
            mine = {o.id: o for o in a.truth if o.features.get("luminance") is not None}
            seen = [(o, mine.get(o.id)) for o in b.truth if o.features.get("luminance") is not None]
            peer: Pose2 | None = a.true_peer
        else:
            anchors = {o.truth: o for o in a.objects if o.truth is not None}
            seen = [(o, anchors.get(o.truth)) for o in b.objects if o.truth is not None]
            peer = a.peer
        for theirs, ours in seen:
            if ours is None:
                continue
            other = dict(theirs.scaled)
            fx, fy = theirs.features.get("x"), theirs.features.get("y")
            if peer is None or fx is None or fy is None:
                other["x"] = other["y"] = None
            else:
                x, y = to_mine(peer, fx, fy)
                other["x"] = scaling.stats["x"].scale(x)
                other["y"] = scaling.stats["y"].scale(y)
            for f in FEATURES:
                va, vb = ours.scaled.get(f), other.get(f)
                if va is not None and vb is not None:
                    pairs[f].append((float(va), float(vb)))
    return pairs


def agreement(pairs: Mapping[str, list[tuple[float, float]]]) -> dict[str, Agreement]:
    """``d``, ``r`` and ``n`` of each feature's pairs."""
    out = {}
    for f, values in pairs.items():
        if not values:
            out[f] = Agreement(None, None, 0)
            continue
        v = np.array(values)
        d = float(np.mean(np.abs(v[:, 0] - v[:, 1])))
        spread = len(v) >= 2 and v[:, 0].std() > 0 and v[:, 1].std() > 0
        r = float(np.corrcoef(v[:, 0], v[:, 1])[0, 1]) if spread else None
        out[f] = Agreement(round(d, 4), None if r is None else round(r, 4), len(v), tuple(values))
    return out
