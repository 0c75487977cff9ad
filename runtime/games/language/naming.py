"""The naming game (Steels 1995; Baronchelli et al. 2006): agents name individual objects.

The speaker says its preferred word for the topic, inventing one when it has none. The hearer
takes the object of its context whose individual the word names best; on success both reward
the association and inhibit its competitors; on failure the speaker punishes its association, and
the hearer, told the topic by pointing, punishes its own and takes up the word for the topic.
"""

from __future__ import annotations

import numpy as np

from percept.runtime.games.language.agents import Agent
from percept.runtime.games.language.dataset.contexts import Context
from percept.runtime.games.language.lexicon import Lexicon, Scores, new_word
from percept.runtime.games.language.outcome import Outcome


class NamingGame:
    """The rules of the naming game; agents hold the state."""

    name = "naming"

    def __init__(self, scores: Scores | None = None) -> None:
        self.scores = scores or Scores()

    def new_agent(self, name: int) -> Agent[str]:
        return Agent(name, Lexicon(self.scores))

    def play(
        self,
        speaker: Agent[str],
        hearer: Agent[str],
        context: Context,
        topic: int,
        rng: np.random.Generator,
    ) -> Outcome:
        meaning = context.speaker_names[topic]
        best = speaker.lexicon.best_word(meaning)
        if best is None:
            word = new_word(rng)
            speaker.lexicon.add(word, meaning)
        else:
            word = best[0]
        scores = [hearer.lexicon.score(word, name) for name in context.hearer_names]
        pick = int(np.argmax(scores)) if max(scores) > 0 else None
        theirs = hearer.lexicon.best_word(context.hearer_names[topic])
        coherent = theirs is not None and theirs[0] == word
        if pick == topic:
            speaker.lexicon.succeeded(word, meaning)
            hearer.lexicon.succeeded(word, context.hearer_names[pick])
            return Outcome(True, word, coherent)
        speaker.lexicon.failed(word, meaning)
        if pick is not None:
            hearer.lexicon.failed(word, context.hearer_names[pick])
        hearer.lexicon.add(word, context.hearer_names[topic])
        return Outcome(False, word, coherent)
