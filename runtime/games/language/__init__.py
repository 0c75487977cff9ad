"""Language games on perceived scenes (SPEC §4.11): pure Python and numpy, a run repeats
exactly for a seed.

- :mod:`~percept.runtime.games.language.records`: the scene data set's records and their JSON
  lines;
- :mod:`~percept.runtime.games.language.agreement`: how far apart the two robots' scaled
  features are;
- :mod:`~percept.runtime.games.language.contexts`: the objects two robots attend to together,
  per game;
- :mod:`~percept.runtime.games.language.lexicon`, :mod:`~percept.runtime.games.language.categories`,
  :mod:`~percept.runtime.games.language.agents`: what an agent knows;
- :mod:`~percept.runtime.games.language.naming`, :mod:`~percept.runtime.games.language.guessing`:
  the games' rules;
- :mod:`~percept.runtime.games.language.population`: a population playing, and the measures;
- :mod:`~percept.runtime.games.language.script`: a game as finite-state machines over messages
  (the API for a researcher's own game), with the guessing game as its example;
- :mod:`~percept.runtime.games.language.figures`: the figures (OpenCV).

The scenes themselves are made by :mod:`percept.runtime.games.language.joint_scenes` (simulation
and both robots' pipelines); ``percept scenes`` and ``percept games`` are the commands.
"""
