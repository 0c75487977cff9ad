"""The optional parts of an install: which extra (``pip install 'percept[X]'``) brings which
module, and the check that a feature's module is there before the feature starts.

A robot's install (``pip install percept``) holds what the daemon runs by default. A feature that
is off by default and needs a library of its own (the simulated world, the ROS 2 side, the
AprilTag C library) names its extra when it is asked for without it: at config load for a key
that enables it, or as the command's exit 2 (``percept.runtime.cli``).
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass


@dataclass(frozen=True)
class Extra:
    """One extra: its name in pyproject.toml and what it brings, for the messages."""

    name: str
    brings: str


EXTRAS: dict[str, Extra] = {
    "mujoco": Extra("sim", "the simulated world (MuJoCo)"),
    "rosbags": Extra("ros2", "the ROS 2 side (rosbags)"),
    "pupil_apriltags": Extra("apriltag", "the AprilTag C library (pupil-apriltags)"),
}
"""By the top-level module each extra installs."""


def installed(module: str) -> bool:
    """Whether the top-level ``module`` can be imported (found, not imported)."""
    return importlib.util.find_spec(module) is not None


def require(module: str) -> None:
    """Fail now, as the import itself would later, when ``module`` is not installed: before
    kernels compile, devices open or child processes start rather than deep inside one."""
    if not installed(module):
        raise ModuleNotFoundError(f"No module named {module!r}", name=module)


def missing(module: str) -> str | None:
    """What to say when ``module`` is missing: the extra that brings it and how to install it;
    None for a module no extra brings (a broken install, not a choice)."""
    extra = EXTRAS.get(module)
    if extra is None:
        return None
    return (
        f"needs {extra.brings}, which this install leaves out: "
        f"pip install 'percept[{extra.name}]' and run it again"
    )
