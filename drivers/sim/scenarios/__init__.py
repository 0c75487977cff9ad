"""Scenes drawn at random: a distribution of scenes, what a room may hold and what may happen in it
(:mod:`.distribution`, read from ``config/scenarios/*.toml``), and the scenes drawn from it
(:mod:`.draw`)."""
