"""Typed settings of a run against the simulated world (the ``[sim]`` table of an experiment)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal


@dataclass(frozen=True)
class SimSettings:
    """How a daemon started with a scene (``percept run --sim SCENE``) gets its joint angles.

    ``emulator``: the simulated angles are pushed into the Dynamixel emulator on a pty and read
    by the real driver (:class:`~percept.drivers.sim.joints.EmulatorBridge`), quantised to encoder
    ticks and as late as a bus read; ``direct``: the exact angles, with no bus in between
    (:class:`~percept.drivers.sim.joints.SimJoints`).
    """

    joints: Literal["emulator", "direct"] = field(
        default="emulator",
        metadata={"doc": "emulator (the real Dynamixel driver on an emulated bus) or direct"},
    )
    push_rate: float = field(
        default=200.0,
        metadata={"min": 1.0, "max": 5000.0, "doc": "emulator: angle updates per second"},
    )
    loop: bool = field(
        default=False,
        metadata={"doc": "start the scene again after its duration (long runs, e.g. a soak)"},
    )
