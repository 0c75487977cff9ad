"""The shipped configuration, and the typed TOML layer every package reads its settings with.

The folders beside this file are the shipped files: ``robots/`` (platform profiles),
``experiments/``, ``scenes/`` (simulated worlds), ``presets/`` (perception parameters),
``scaling/`` (feature statistics), ``lab/`` (the lab router) and ``scenarios/`` (distributions
of scenes for ``percept scenarios``). They are package data, found with
:mod:`importlib.resources`, so an installed percept has them wherever it is installed;
``percept init DIR`` copies them into a folder a user edits. Every command that takes such a file
takes a path or the name of a shipped one (:func:`find`).

:mod:`percept.config.loader` turns a TOML file into the typed, validated settings that the
lower packages declare; it imports nothing of percept, so every layer can use it.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from percept.config.loader import ConfigError

KINDS = {
    "robots": "robot profile",
    "experiments": "experiment",
    "scenes": "scene",
    "presets": "perception preset",
    "scaling": "feature statistics file",
    "lab": "lab file",
    "scenarios": "scene distribution",
}


def shipped_dir() -> Path:
    """The folder of the shipped files in the installed package."""
    return Path(str(files(__name__)))


def shipped(kind: str) -> list[str]:
    """The names of the shipped files of ``kind`` (a key of :data:`KINDS`)."""
    return sorted(p.stem for p in (shipped_dir() / kind).glob("*.toml"))


def find(kind: str, name: str | Path) -> Path:
    """The file ``name``: a path, or the bare name (no folder, no ``.toml``) of a shipped file of
    ``kind``. A path is returned as it is, for the loader to say what is wrong with it."""
    path = Path(name).expanduser()
    if path.is_file() or path.suffix == ".toml" or len(path.parts) != 1:
        return path
    candidate = shipped_dir() / kind / f"{path.name}.toml"
    if candidate.is_file():
        return candidate
    known = ", ".join(shipped(kind))
    raise ConfigError(path, "", f"no such file, nor a shipped {KINDS[kind]} (shipped: {known})")


def shipped_name(kind: str, path: str | Path) -> str | None:
    """The bare name of ``path`` if it is a shipped file of ``kind`` (``find`` finds it again by
    that name wherever percept is installed), else None."""
    candidate = Path(path).expanduser()
    if candidate.suffix != ".toml" or candidate.stem not in shipped(kind):
        return None
    if candidate.resolve() != (shipped_dir() / kind / candidate.name).resolve():
        return None
    return candidate.stem


def portable_name(kind: str, name: str | Path) -> str:
    """How a record names the file ``name`` (a path or a shipped name, as :func:`find` takes):
    a shipped file by its bare name, any other by its absolute path, so that the record is read
    the same from any folder and with percept installed anywhere."""
    path = find(kind, name)
    return shipped_name(kind, path) or str(path.resolve())
