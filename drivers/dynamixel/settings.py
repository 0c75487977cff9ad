"""Typed settings of a Dynamixel bus and its joints (the ``[bus]`` and ``[[joints]]`` tables of a
platform profile)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from percept.drivers.backoff import check_backoff
from percept.drivers.dynamixel.models import MODEL_NAMES, is_known_model

if TYPE_CHECKING:
    # PEP 586 admits no float literals, so to the type checker a protocol is just a float.
    ProtocolVersion = float
else:
    # The config loader reads this annotation at run time and accepts only these two versions.
    ProtocolVersion = Literal[1.0, 2.0]


@dataclass(frozen=True)
class BusSettings:
    """One serial bus of Dynamixel servos."""

    port: str = field(
        default="/dev/ttyUSB0",
        metadata={
            "doc": "serial device; prefer /dev/serial/by-id/... paths, they survive replugging"
        },
    )
    baudrate: int = field(
        default=1_000_000, metadata={"min": 9600, "max": 10_500_000, "doc": "bits per second"}
    )
    protocol: ProtocolVersion = field(default=2.0, metadata={"doc": "Dynamixel protocol"})
    timeout: float = field(
        default=0.02,
        metadata={"min": 0.001, "max": 1.0, "doc": "seconds to wait for a reply packet"},
    )
    rate: float = field(
        default=100.0,
        metadata={"min": 1.0, "max": 1000.0, "doc": "present-position reads per second"},
    )
    retries: int = field(
        default=2, metadata={"min": 0, "max": 10, "doc": "extra attempts after a failed read"}
    )
    stale_after: float = field(
        default=0.1,
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "seconds without an answer after which a joint is stale",
        },
    )
    error_poll_interval: float = field(
        default=1.0,
        metadata={
            "min": 0.05,
            "max": 86400.0,
            "doc": "seconds between hardware-error status polls",
        },
    )
    probe_interval: float = field(
        default=0.25,
        metadata={
            "min": 0.01,
            "max": 86400.0,
            "doc": "seconds between attempts to reach a servo that stopped answering",
        },
    )
    reconnect_backoff: tuple[float, float] = field(
        default=(0.1, 2.0),
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "first and largest wait in seconds between reconnect attempts",
        },
    )

    def __post_init__(self) -> None:
        check_backoff(self.reconnect_backoff)
        if self.stale_after < 2.0 / self.rate:
            # Shorter, and a joint would flap between stale and fresh between two reads.
            raise ValueError(
                f"stale_after ({self.stale_after} s) must be at least two read periods "
                f"({2.0 / self.rate:g} s at rate {self.rate:g})"
            )


@dataclass(frozen=True)
class JointSettings:
    """One servo: which id it has on the bus and how its ticks map to the joint angle.

    ``angle = sign * (ticks - zero_tick) * 2*pi / ticks_per_rev`` in radians.
    """

    name: str = field(metadata={"doc": "joint name, as in the kinematic chain"})
    id: int = field(metadata={"min": 0, "max": 252, "doc": "servo id on the bus"})
    model: str = field(
        default="XM430-W350",
        metadata={"doc": "servo model (control table), e.g. XM430-W350, MX-28, AX-12A"},
    )
    ticks_per_rev: float = field(
        default=4096.0,
        metadata={
            "min": 2,
            "max": 1_000_000,
            "doc": "encoder ticks per full turn (AX-12: 1024 per 300 deg = 1228.8)",
        },
    )
    zero_tick: int = field(
        default=2048, metadata={"min": 0, "max": 1_000_000, "doc": "ticks at joint angle 0"}
    )
    sign: Literal[-1, 1] = field(default=1, metadata={"doc": "+1 or -1: direction of the joint"})
    min: float = field(
        default=-math.pi,
        metadata={"min": -100.0, "max": 100.0, "doc": "lower joint limit, radians"},
    )
    max: float = field(
        default=math.pi, metadata={"min": -100.0, "max": 100.0, "doc": "upper joint limit, radians"}
    )

    def __post_init__(self) -> None:
        if not is_known_model(self.model):
            raise ValueError(
                f"unknown servo model {self.model!r}; expected one of: {', '.join(MODEL_NAMES)}"
            )
        if self.min >= self.max:
            raise ValueError(f"min ({self.min}) must be below max ({self.max})")


WATCHDOG_UNIT = 0.02
"""Seconds per unit of the Protocol 2.0 Bus Watchdog register (address 98, 1..127 units)."""


@dataclass(frozen=True)
class GazeSettings:
    """Whether and how the head is moved: the joints written to, how fast, what happens to the
    torque when the writer stops, and the bus watchdog that stops the head if it dies.

    Nothing is written to a servo unless ``enabled`` (or a person says so on the command line).
    Goals are always clipped to each joint's ``min``/``max`` by the driver.
    """

    enabled: bool = field(
        default=False,
        metadata={"doc": "move the head; false: servos are only read (nothing moves)"},
    )
    joints: tuple[str, ...] = field(
        default=("head_pan", "head_tilt"),
        metadata={"doc": "joints whose servos are written (they must be in the profile)"},
    )
    max_speed: float = field(
        default=1.0,
        metadata={"min": 0.01, "max": 20.0, "doc": "fastest joint speed asked for, rad/s"},
    )
    torque_at_stop: Literal["hold", "release"] = field(
        default="hold",
        metadata={
            "doc": "when gaze stops: hold (torque stays on where the head is) or release (off)"
        },
    )
    watchdog: float = field(
        default=0.2,
        metadata={
            "min": WATCHDOG_UNIT,
            "max": 127 * WATCHDOG_UNIT,
            "doc": "Protocol 2.0 bus watchdog, seconds: a head stops this long after the last "
            "packet",
        },
    )

    def __post_init__(self) -> None:
        if not self.joints:
            raise ValueError("joints: name at least one joint to move")
        if len(set(self.joints)) != len(self.joints):
            raise ValueError(f"joints: named twice in {list(self.joints)}")
