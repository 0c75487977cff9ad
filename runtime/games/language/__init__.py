"""Language games on perceived scenes (SPEC §4.11): pure Python and numpy, a run repeats
exactly for a seed.

- :mod:`~percept.runtime.games.language.dataset`: the scene data set the games are played on,
  made by :mod:`~percept.runtime.games.language.dataset.joint_scenes` (simulation and both
  robots' pipelines): its records and their JSON lines (:mod:`~.dataset.records`), how far apart
  the two robots' scaled features are (:mod:`~.dataset.agreement`), and the objects two robots
  attend to together, per game (:mod:`~.dataset.contexts`);
- :mod:`~percept.runtime.games.language.lexicon`, :mod:`~percept.runtime.games.language.categories`,
  :mod:`~percept.runtime.games.language.agents`: what an agent knows;
- :mod:`~percept.runtime.games.language.naming`, :mod:`~percept.runtime.games.language.guessing`:
  the games' rules;
- :mod:`~percept.runtime.games.language.population`: a population playing, and the measures;
- :mod:`~percept.runtime.games.language.script`: a game as finite-state machines over messages
  (the API for a researcher's own game), with the guessing game as its example;
- :mod:`~percept.runtime.games.language.figures`: the figures (OpenCV).

``percept scenes`` and ``percept games`` are the commands.
"""
