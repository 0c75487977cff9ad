"""Language games on perceived scenes (SPEC §4.11): pure Python and numpy, a run repeats
exactly for a seed.

- :mod:`~runtime.language.records`: the scene data set's records and their JSON lines;
- :mod:`~runtime.language.agreement`: how far apart the two robots' scaled features are;
- :mod:`~runtime.language.contexts`: the objects two robots attend to together, per game;
- :mod:`~runtime.language.lexicon`, :mod:`~runtime.language.categories`,
  :mod:`~runtime.language.agents`: what an agent knows;
- :mod:`~runtime.language.naming`, :mod:`~runtime.language.guessing`: the games' rules;
- :mod:`~runtime.language.population`: a population playing, and the measures;
- :mod:`~runtime.language.script`: a game as finite-state machines over messages (the API for a
  researcher's own game), with the guessing game as its example;
- :mod:`~runtime.language.figures`: the figures (OpenCV).

The scenes themselves are made by :mod:`runtime.joint_scenes` (simulation and both robots'
pipelines); ``percept scenes`` and ``percept games`` are the commands.
"""
