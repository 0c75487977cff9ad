"""A population playing games: who plays with whom on which scene, and what is measured.

Each game draws a context (a scene with a speaker and a hearer robot), two different agents for
the two roles and a topic, from one numpy Generator: the same seed gives the same run. Measured
as in the thesis: communicative success and coherence (the hearer would have said the speaker's
word for the topic) over a window of games, and the mean lexicon size (word forms) and number of
categories per agent.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from percept.runtime.games.language.agents import Agent
from percept.runtime.games.language.dataset.contexts import Context
from percept.runtime.games.language.lexicon import Meaning
from percept.runtime.games.language.outcome import Outcome


class Game(Protocol[Meaning]):
    """What a population plays: its agents and the rules of one game."""

    name: str

    def new_agent(self, name: int) -> Agent[Meaning]: ...

    def play(
        self,
        speaker: Agent[Meaning],
        hearer: Agent[Meaning],
        context: Context,
        topic: int,
        rng: np.random.Generator,
    ) -> Outcome: ...


@dataclass
class History:
    """Measures every ``every`` games: success and coherence over the last ``window`` games,
    mean lexicon size and categories per agent."""

    games: list[int] = field(default_factory=list)
    success: list[float] = field(default_factory=list)
    coherence: list[float] = field(default_factory=list)
    lexicon: list[float] = field(default_factory=list)
    categories: list[float] = field(default_factory=list)
    outcomes: list[bool] = field(default_factory=list, repr=False)

    def success_over(self, last: int, until: int | None = None) -> float:
        """Communicative success over the ``last`` games before game ``until`` (default: all)."""
        end = len(self.outcomes) if until is None else until
        part = self.outcomes[max(0, end - last) : end]
        return float(np.mean(part)) if part else 0.0


def play(
    game: Game[Meaning],
    contexts: Sequence[Context],
    agents: int,
    games: int,
    seed: int,
    window: int = 1000,
    every: int = 100,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[list[Agent[Meaning]], History]:
    """``games`` games of ``agents`` agents on ``contexts``."""
    if agents < 2:
        raise ValueError("a game needs at least two agents")
    if not contexts:
        raise ValueError("no context to play in (no scene with objects both robots see)")
    rng = np.random.default_rng(seed)
    population = [game.new_agent(i) for i in range(agents)]
    history = History()
    recent: deque[tuple[bool, bool]] = deque(maxlen=window)
    began = time.monotonic()
    for g in range(1, games + 1):
        context = contexts[int(rng.integers(len(contexts)))]
        s, h = rng.choice(agents, size=2, replace=False)
        topic = int(rng.integers(len(context)))
        out = game.play(population[s], population[h], context, topic, rng)
        history.outcomes.append(out.success)
        recent.append((out.success, out.coherent))
        if g % every == 0 or g == games:
            history.games.append(g)
            history.success.append(float(np.mean([r[0] for r in recent])))
            history.coherence.append(float(np.mean([r[1] for r in recent])))
            history.lexicon.append(float(np.mean([len(a.lexicon) for a in population])))
            history.categories.append(
                float(np.mean([len(a.categories) if a.categories else 0 for a in population]))
            )
            if progress is not None and time.monotonic() - began > 1.0:
                progress(g, games)
                began = time.monotonic()
    return population, history
