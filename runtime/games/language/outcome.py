"""How one game ended."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Outcome:
    """``success``: the hearer chose the topic; ``word``: what the speaker said (None: it
    found nothing to say); ``coherent``: the hearer would have said the same for the topic."""

    success: bool
    word: str | None
    coherent: bool
