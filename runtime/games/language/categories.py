"""Categories over the scaled features: what a word of the guessing game means.

An object is a row of scaled feature values (0..1, NaN when unknown), one column per channel.
Two kinds of category, with the same four operations (find those that tell the topic apart from
the rest of the context, grow new ones when none does, find the object a category picks out,
adapt one to a topic):

- :class:`Prototypes` (the default): a category is a prototype value on one channel; an object
  falls into the category of the nearest prototype on each channel. A category discriminates the
  topic when the topic falls into it and no other object does.
- :class:`DiscriminationTrees` (Steels' discrimination game): each channel's range is split in
  halves, and those again, on demand; a category is one interval of that tree. It discriminates
  when it holds the topic's value and no other object's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MERGE = 0.02  # a new prototype closer than this to an old one on its channel is not made
DEPTH = 8  # discrimination trees split an interval at most this often


@dataclass(frozen=True)
class Category:
    """A category: its id (unique within its agent) and its channel."""

    id: int
    channel: int


def distinct_channel(values: np.ndarray, topic: int, channels: np.ndarray) -> int | None:
    """The channel on which the topic lies farthest from its nearest other object (None when
    the topic is unknown on every channel): where a new category has the best chance."""
    best, where = -1.0, None
    others = np.delete(values, topic, axis=0)
    for ch in channels:
        v = values[topic, ch]
        if np.isnan(v):
            continue
        gap = np.nanmin(np.abs(others[:, ch] - v)) if len(others) else 1.0
        gap = 1.0 if np.isnan(gap) else float(gap)
        if gap > best:
            best, where = gap, int(ch)
    return where


class Prototypes:
    """Prototype categories, one value each on one channel."""

    def __init__(self, channels: int) -> None:
        self.channels = np.arange(channels)
        self._values: list[np.ndarray] = [np.zeros(0) for _ in range(channels)]
        self._ids: list[list[int]] = [[] for _ in range(channels)]
        self._where: dict[int, tuple[int, int]] = {}  # id: (channel, index)

    def __len__(self) -> int:
        return len(self._where)

    def _nearest(self, values: np.ndarray, ch: int) -> np.ndarray:
        """Per object the index of the nearest prototype on ``ch`` (-1: unknown or none)."""
        protos = self._values[ch]
        v = values[:, ch]
        if not len(protos):
            return np.full(len(v), -1)
        out = np.abs(v[:, None] - protos[None, :]).argmin(axis=1)
        return np.where(np.isnan(v), -1, out)

    def discriminating(self, values: np.ndarray, topic: int) -> list[Category]:
        out = []
        for ch in map(int, self.channels):
            near = self._nearest(values, ch)
            k = near[topic]
            if k >= 0 and np.count_nonzero(near == k) == 1:
                out.append(Category(self._ids[ch][k], ch))
        return out

    def grow(self, values: np.ndarray, topic: int, next_id: int) -> int:
        """New prototypes on the most telling channel, at the topic's value and at the values of
        the objects that share its category; returns the next free id."""
        ch = distinct_channel(values, topic, self.channels)
        if ch is None:
            return next_id
        near = self._nearest(values, ch)
        same = [i for i in range(len(values)) if near[i] == near[topic] and i != topic]
        for i in [topic, *same]:
            v = float(values[i, ch])
            if np.isnan(v) or (
                len(self._values[ch]) and np.abs(self._values[ch] - v).min() < MERGE
            ):
                continue
            self._where[next_id] = (ch, len(self._ids[ch]))
            self._values[ch] = np.append(self._values[ch], v)
            self._ids[ch].append(next_id)
            next_id += 1
        return next_id

    def pick(self, category: Category, values: np.ndarray) -> int | None:
        """The object nearest to the prototype on its channel (None: all unknown there)."""
        ch, k = self._where[category.id]
        d = np.abs(values[:, ch] - self._values[ch][k])
        return None if np.all(np.isnan(d)) else int(np.nanargmin(d))

    def adapt(self, category: Category, value: float, rate: float) -> None:
        """Move the prototype towards ``value``."""
        ch, k = self._where[category.id]
        if not np.isnan(value):
            self._values[ch][k] += rate * (value - self._values[ch][k])


class DiscriminationTrees:
    """Binary trees of intervals over each channel's range 0..1 (the root is not a category;
    its halves are, once it is split)."""

    def __init__(self, channels: int) -> None:
        self.channels = np.arange(channels)
        self._ids: dict[tuple[int, float, float], int] = {}  # (channel, low, high): id
        self._nodes: dict[int, tuple[int, float, float]] = {}
        self._split: set[tuple[int, float, float]] = set()

    def __len__(self) -> int:
        return len(self._nodes)

    def _path(self, ch: int, v: float) -> list[tuple[int, float, float]]:
        """The intervals holding ``v`` on channel ``ch``, widest first."""
        out, lo, hi = [], 0.0, 1.0
        while (ch, lo, hi) in self._split:
            mid = (lo + hi) / 2
            lo, hi = (lo, mid) if v < mid else (mid, hi)
            out.append((ch, lo, hi))
        return out

    def discriminating(self, values: np.ndarray, topic: int) -> list[Category]:
        # Plain floats: the contexts are a handful of objects, where numpy's per-call cost
        # would dominate.
        rows = values.tolist()
        out = []
        for ch in self.channels.tolist():
            v = rows[topic][ch]
            if math.isnan(v):
                continue
            others = [r[ch] for i, r in enumerate(rows) if i != topic and not math.isnan(r[ch])]
            for node in self._path(ch, v):
                _, lo, hi = node
                if not any(lo <= w < hi or (hi == 1.0 and w == 1.0) for w in others):
                    out.append(Category(self._ids[node], ch))
        return out

    def grow(self, values: np.ndarray, topic: int, next_id: int) -> int:
        """Split the smallest interval holding the topic on the most telling channel."""
        ch = distinct_channel(values, topic, self.channels)
        if ch is None:
            return next_id
        path = self._path(ch, float(values[topic, ch]))
        if len(path) >= DEPTH:
            return next_id
        _, lo, hi = path[-1] if path else (ch, 0.0, 1.0)
        self._split.add((ch, lo, hi))
        mid = (lo + hi) / 2
        for interval in ((ch, lo, mid), (ch, mid, hi)):
            self._ids[interval] = next_id
            self._nodes[next_id] = interval
            next_id += 1
        return next_id

    def pick(self, category: Category, values: np.ndarray) -> int | None:
        """The object nearest to the middle of the interval."""
        ch, lo, hi = self._nodes[category.id]
        d = np.abs(values[:, ch] - (lo + hi) / 2)
        return None if np.all(np.isnan(d)) else int(np.nanargmin(d))

    def adapt(self, category: Category, value: float, rate: float) -> None:
        """Intervals do not move."""


Conceptualiser = Prototypes | DiscriminationTrees


def make_categories(kind: str, channels: int) -> Conceptualiser:
    """``prototypes`` or ``trees`` over ``channels`` channels."""
    if kind == "prototypes":
        return Prototypes(channels)
    if kind == "trees":
        return DiscriminationTrees(channels)
    raise ValueError(f"unknown kind of category {kind!r}: prototypes or trees")
