"""The shipped configuration, and the typed TOML layer that every package reads its settings with.

The folders beside this file (robots, experiments, scenes, presets, scaling, lab) are the
shipped profiles and files; :func:`shipped` finds one by kind and name in the installed
package, and ``percept init DIR`` copies them into a folder a user edits.
"""
