"""A population's agent: a lexicon, categories, and the ids of the categories it made."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Generic

import numpy as np

from percept.runtime.games.language.categories import Conceptualiser
from percept.runtime.games.language.lexicon import Lexicon, Meaning


@dataclass
class Agent(Generic[Meaning]):
    """One agent of a population. ``categories`` is None in games without categories (the
    naming game names individuals); ``most_categories``: it makes no new ones once it holds
    this many (None: no bound)."""

    name: int
    lexicon: Lexicon[Meaning]
    categories: Conceptualiser | None = None
    next_category: int = field(default=0)
    most_categories: int | None = None

    def grow(self, values: np.ndarray, topic: int) -> None:
        """New categories for a topic none of its categories tells apart (none when it holds
        ``most_categories`` already: the game goes on as when no channel tells it apart)."""
        assert self.categories is not None
        if self.most_categories is not None and len(self.categories) >= self.most_categories:
            return
        self.next_category = self.categories.grow(values, topic, self.next_category)
