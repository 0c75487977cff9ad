"""The per-robot daemon, configuration loading, messaging, recording and the ``percept`` CLI.

``runtime`` sits on top: it reads the TOML files, builds the typed parameters that the lower
folders (``drivers``, ``kinematics``, ``perception``) define, and wires them together.
Nothing imports ``runtime``.
"""
