"""The guessing game (Steels' Talking Heads; Loetzsch's thesis, chapter 8).

1. The speaker finds the categories that tell the topic apart from the rest of the context
   (:mod:`percept.runtime.games.language.categories`); when none does, it makes new ones and
   the game fails.
2. It says its best-scored word for one of them (inventing a word for one when none has any).
3. The hearer takes the best-scored meaning of the word and picks the object that category
   picks out in its own view of the context; it fails when it knows no meaning.
4. Success when that is the topic (the speaker sees where the hearer points): both reward their
   association, inhibit its competitors and move the category towards the topic.
   Failure: both punish the association used; the speaker points at the topic, and the hearer
   associates the word with each category that tells the topic apart in its view (making new
   ones when none does), to be sorted out by later games.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from percept.runtime.games.language.agents import Agent
from percept.runtime.games.language.categories import Category, make_categories
from percept.runtime.games.language.dataset.contexts import Context
from percept.runtime.games.language.lexicon import Lexicon, Scores, new_word
from percept.runtime.games.language.outcome import Outcome


@dataclass(frozen=True)
class GuessingSettings:
    """``categories``: ``prototypes`` or ``trees``; ``shift``: how far a prototype moves
    towards the topic after a success; ``words`` and ``most_categories``: what an agent holds
    at most (None: no bound; see :class:`Lexicon` and :class:`Agent` for what goes)."""

    categories: str = "prototypes"
    scores: Scores = field(default_factory=Scores)
    shift: float = 0.05
    words: int | None = None
    most_categories: int | None = None


class GuessingGame:
    """The rules of the guessing game over ``channels`` feature channels."""

    name = "guessing"

    def __init__(self, channels: int, settings: GuessingSettings | None = None) -> None:
        self.channels = channels
        self.settings = settings or GuessingSettings()
        make_categories(self.settings.categories, channels)  # an unknown kind fails here

    def new_agent(self, name: int) -> Agent[Category]:
        return Agent(
            name,
            Lexicon(self.settings.scores, self.settings.words),
            make_categories(self.settings.categories, self.channels),
            most_categories=self.settings.most_categories,
        )

    def produce(
        self, agent: Agent[Category], values: np.ndarray, topic: int
    ) -> tuple[list[Category], str | None, Category | None]:
        """The agent's categories for the topic, and its best word and the category it says."""
        assert agent.categories is not None
        found = agent.categories.discriminating(values, topic)
        best: tuple[float, str | None, Category | None] = (0.0, None, None)
        for category in found:
            said = agent.lexicon.best_word(category)
            if said is not None and said[1] > best[0]:
                best = (said[1], said[0], category)
        return found, best[1], best[2]

    def interpret(
        self, agent: Agent[Category], word: str, values: np.ndarray
    ) -> tuple[int | None, Category | None]:
        """The object the agent takes the word to mean, and the category it took: the
        best-scored meaning that tells one object apart in its view (the speaker says only such
        categories), else the object nearest to the best-scored meaning."""
        assert agent.categories is not None
        meanings = agent.lexicon.meanings(word)
        if not meanings:
            return None, None
        apart = {
            category: j
            for j in range(len(values))
            for category in agent.categories.discriminating(values, j)
        }
        for meaning, _ in meanings:
            if meaning in apart:
                return apart[meaning], meaning
        best = meanings[0][0]
        return agent.categories.pick(best, values), best

    def speak(
        self, agent: Agent[Category], values: np.ndarray, topic: int, rng: np.random.Generator
    ) -> tuple[str, Category] | None:
        """The speaker's turn: its word and the category it says for the topic; None (after it
        made new categories) when none of its categories tells the topic apart."""
        found, word, category = self.produce(agent, values, topic)
        if not found:
            agent.grow(values, topic)
            return None
        if word is None or category is None:
            category = found[int(rng.integers(len(found)))]
            word = new_word(rng)
            agent.lexicon.add(word, category)
        return word, category

    def learn(
        self,
        agent: Agent[Category],
        word: str,
        used: Category | None,
        values: np.ndarray,
        topic: int,
        success: bool,
        hearer: bool,
    ) -> None:
        """Either side's adaptation once the topic is known: reward (and move the category
        towards the topic) or punish the association ``used``; a hearer that failed takes the
        word up for the categories that tell the topic apart in its view."""
        assert agent.categories is not None
        if used is not None and success:
            agent.lexicon.succeeded(word, used)
            agent.categories.adapt(used, values[topic, used.channel], self.settings.shift)
            return
        if used is not None:
            agent.lexicon.failed(word, used)
        if not hearer:
            return
        known = agent.categories.discriminating(values, topic)
        if not known:
            agent.grow(values, topic)
            known = agent.categories.discriminating(values, topic)
        for category in known:
            agent.lexicon.add(word, category)

    def play(
        self,
        speaker: Agent[Category],
        hearer: Agent[Category],
        context: Context,
        topic: int,
        rng: np.random.Generator,
    ) -> Outcome:
        mine, theirs = context.speaker_values, context.hearer_values
        said = self.speak(speaker, mine, topic, rng)
        if said is None:
            return Outcome(False, None, False)
        word, category = said
        pick, meaning = self.interpret(hearer, word, theirs)
        coherent = self.produce(hearer, theirs, topic)[1] == word
        success = pick == topic
        self.learn(speaker, word, category, mine, topic, success, hearer=False)
        self.learn(hearer, word, meaning, theirs, topic, success, hearer=True)
        return Outcome(success, word, coherent)
