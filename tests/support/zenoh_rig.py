"""Helpers for tests that run real Zenoh sessions on 127.0.0.1."""

from __future__ import annotations

from pathlib import Path

from percept.runtime.net.ports import free_port
from percept.runtime.settings.experiment import Experiment, RobotEntry

PROFILE = Path(__file__).resolve().parents[2] / "config" / "robots" / "robotis-op3.toml"


def experiment(*names: str, **fields: object) -> Experiment:
    """An experiment whose robots listen on free local ports."""
    robots = tuple(RobotEntry(n, PROFILE, f"tcp/127.0.0.1:{free_port()}") for n in names)
    return Experiment(name="test", robots=robots, **fields)  # type: ignore[arg-type]
