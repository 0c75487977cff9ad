"""An agent's lexicon: scored associations between word forms and meanings (Steels' games).

A meaning is anything hashable: an individual object's name in the naming game, a category in
the guessing game. Scores lie in (0, 1]; an association whose score falls to 0 or below is
forgotten. Success raises the used association by ``reward`` and lowers its competitors by
``inhibition`` (lateral inhibition: other words for the same meaning, other meanings of the same
word); failure lowers it by ``punish``. Everything is kept in insertion order, so a run repeats
exactly. A lexicon may hold at most ``most`` word forms: a new one then pushes out the word form
whose best association is the weakest (the oldest of equals), with all its associations.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterator
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

#: What a lexicon's words mean: an individual's name (``str``), a category.
Meaning = TypeVar("Meaning", bound=Hashable)
K = TypeVar("K", bound=Hashable)
V = TypeVar("V", bound=Hashable)

SYLLABLES = tuple(c + v for c in "bdfgklmnprstvz" for v in "aeiou")


@dataclass(frozen=True)
class Scores:
    """How associations change: ``initial`` for a new one, ``reward`` on success, ``inhibition``
    of competitors on success, ``punish`` on failure."""

    initial: float = 0.5
    reward: float = 0.1
    inhibition: float = 0.2
    punish: float = 0.1


class Lexicon(Generic[Meaning]):
    """Word-meaning associations with scores, indexed both ways."""

    def __init__(self, scores: Scores | None = None, most: int | None = None) -> None:
        self.scores = scores or Scores()
        self.most = most
        self._by_word: dict[str, dict[Meaning, float]] = {}
        self._by_meaning: dict[Meaning, dict[str, float]] = {}

    def __len__(self) -> int:
        """How many word forms it holds."""
        return len(self._by_word)

    def words(self) -> Iterator[str]:
        return iter(self._by_word)

    def score(self, word: str, meaning: Meaning) -> float:
        return self._by_word.get(word, {}).get(meaning, 0.0)

    def meanings(self, word: str) -> list[tuple[Meaning, float]]:
        """The meanings of ``word``, best first (ties: the older first)."""
        found = self._by_word.get(word, {})
        return sorted(found.items(), key=lambda item: -item[1])

    def best_word(self, meaning: Meaning) -> tuple[str, float] | None:
        """The word preferred for ``meaning`` and its score, or None."""
        found = self._by_meaning.get(meaning)
        if not found:
            return None
        word = max(found, key=found.__getitem__)
        return word, found[word]

    def add(self, word: str, meaning: Meaning, score: float | None = None) -> None:
        """Associate ``word`` with ``meaning`` (kept as it is when already associated)."""
        if meaning in self._by_word.get(word, {}):
            return
        self._set(word, meaning, self.scores.initial if score is None else score)

    def succeeded(self, word: str, meaning: Meaning) -> None:
        """Reward the association used, inhibit its competitors."""
        self._set(word, meaning, min(1.0, self.score(word, meaning) + self.scores.reward))
        for other_word, s in list(self._by_meaning.get(meaning, {}).items()):
            if other_word != word:
                self._set(other_word, meaning, s - self.scores.inhibition)
        for other_meaning, s in list(self._by_word.get(word, {}).items()):
            if other_meaning != meaning:
                self._set(word, other_meaning, s - self.scores.inhibition)

    def failed(self, word: str, meaning: Meaning) -> None:
        """Punish the association used."""
        if meaning in self._by_word.get(word, {}):
            self._set(word, meaning, self.score(word, meaning) - self.scores.punish)

    def _set(self, word: str, meaning: Meaning, score: float) -> None:
        if score > 0.0:
            if word not in self._by_word and self.most is not None:
                while len(self._by_word) >= self.most:
                    self._drop_weakest()
            self._by_word.setdefault(word, {})[meaning] = score
            self._by_meaning.setdefault(meaning, {})[word] = score
            return
        _forget(self._by_word, word, meaning)
        _forget(self._by_meaning, meaning, word)

    def _drop_weakest(self) -> None:
        """Forget the word form whose best association is the weakest (the oldest of equals)."""
        weakest = min(self._by_word, key=lambda w: max(self._by_word[w].values()))
        for meaning in self._by_word.pop(weakest):
            _forget(self._by_meaning, meaning, weakest)


def _forget(index: dict[K, dict[V, float]], key: K, inner: V) -> None:
    """Drop ``index[key][inner]``, and ``index[key]`` once it is empty."""
    table = index.get(key)
    if table is not None:
        table.pop(inner, None)
        if not table:
            del index[key]


def new_word(rng: np.random.Generator) -> str:
    """A fresh word form of three syllables."""
    return "".join(SYLLABLES[int(i)] for i in rng.integers(0, len(SYLLABLES), 3))
