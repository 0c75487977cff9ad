"""Servo models and their control tables (the registers the driver reads and the emulator serves).

Addresses and defaults follow the ROBOTIS e-Manual: the X series (and MX with firmware 2.0) on
Protocol 2.0; MX-28/64/106 and AX/RX on Protocol 1.0. The speed a goal position is approached
with is a register of its own (2.0: profile velocity, 1.0: moving speed), counted in a unit of
revolutions per minute of the servo's shaft (``speed_unit``, here in radians per second); the
register that follows it holds the goal position (1.0: precedes it), so one write sets both.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from percept.drivers.dynamixel.protocol import Error1


@dataclass(frozen=True)
class Register:
    """One control-table entry; multi-byte values are little-endian."""

    address: int
    size: int
    default: int = 0
    writable: bool = True


@dataclass(frozen=True)
class ControlTable:
    """The registers of one family of servos on one protocol."""

    protocol: float
    size: int
    registers: Mapping[str, Register]
    position_signed: bool
    """Protocol 2.0 present position is a signed 32-bit value (multi-turn modes)."""
    speed_register: str
    """The register that limits the speed towards a goal position (0 there means "no limit")."""
    speed_unit: float
    """Radians per second of the shaft per unit of the speed register."""

    def __getitem__(self, name: str) -> Register:
        return self.registers[name]


_RPM = 2.0 * math.pi / 60.0


def _table(
    protocol: float,
    signed: bool,
    speed: tuple[str, float],
    rows: dict[str, tuple[int, int, int, bool]],
) -> ControlTable:
    registers = {name: Register(*row) for name, row in rows.items()}
    size = max(r.address + r.size for r in registers.values())
    register, rpm = speed
    return ControlTable(protocol, size, MappingProxyType(registers), signed, register, rpm * _RPM)


R, W = False, True

X_SERIES = _table(
    2.0,
    True,
    ("profile_velocity", 0.229),
    {
        "model_number": (0, 2, 0, R),
        "model_information": (2, 4, 0, R),
        "firmware_version": (6, 1, 0, R),
        "id": (7, 1, 1, W),
        "baud_rate": (8, 1, 1, W),
        "return_delay_time": (9, 1, 250, W),
        "drive_mode": (10, 1, 0, W),
        "operating_mode": (11, 1, 3, W),
        "secondary_id": (12, 1, 255, W),
        "protocol_type": (13, 1, 2, W),
        "homing_offset": (20, 4, 0, W),
        "moving_threshold": (24, 4, 10, W),
        "temperature_limit": (31, 1, 80, W),
        "max_voltage_limit": (32, 2, 160, W),
        "min_voltage_limit": (34, 2, 95, W),
        "pwm_limit": (36, 2, 885, W),
        "current_limit": (38, 2, 1193, W),
        "velocity_limit": (44, 4, 200, W),
        "max_position_limit": (48, 4, 4095, W),
        "min_position_limit": (52, 4, 0, W),
        "startup_configuration": (60, 1, 0, W),
        "shutdown": (63, 1, 52, W),
        "torque_enable": (64, 1, 0, W),
        "led": (65, 1, 0, W),
        "status_return_level": (68, 1, 2, W),
        "registered_instruction": (69, 1, 0, R),
        "hardware_error_status": (70, 1, 0, R),
        "velocity_i_gain": (76, 2, 1920, W),
        "velocity_p_gain": (78, 2, 100, W),
        "position_d_gain": (80, 2, 0, W),
        "position_i_gain": (82, 2, 0, W),
        "position_p_gain": (84, 2, 800, W),
        "feedforward_2nd_gain": (88, 2, 0, W),
        "feedforward_1st_gain": (90, 2, 0, W),
        "bus_watchdog": (98, 1, 0, W),
        "goal_pwm": (100, 2, 885, W),
        "goal_current": (102, 2, 1193, W),
        "goal_velocity": (104, 4, 0, W),
        "profile_acceleration": (108, 4, 0, W),
        "profile_velocity": (112, 4, 0, W),
        "goal_position": (116, 4, 2048, W),
        "realtime_tick": (120, 2, 0, R),
        "moving": (122, 1, 0, R),
        "moving_status": (123, 1, 0, R),
        "present_pwm": (124, 2, 0, R),
        "present_current": (126, 2, 0, R),
        "present_velocity": (128, 4, 0, R),
        "present_position": (132, 4, 2048, R),
        "velocity_trajectory": (136, 4, 0, R),
        "position_trajectory": (140, 4, 0, R),
        "present_input_voltage": (144, 2, 120, R),
        "present_temperature": (146, 1, 30, R),
        "backup_ready": (147, 1, 0, R),
    },
)

_V1_COMMON = {
    "model_number": (0, 2, 0, R),
    "firmware_version": (2, 1, 0, R),
    "id": (3, 1, 1, W),
    "baud_rate": (4, 1, 1, W),
    "return_delay_time": (5, 1, 250, W),
    "cw_angle_limit": (6, 2, 0, W),
    "ccw_angle_limit": (8, 2, 4095, W),
    "temperature_limit": (11, 1, 80, W),
    "min_voltage_limit": (12, 1, 60, W),
    "max_voltage_limit": (13, 1, 160, W),
    "max_torque": (14, 2, 1023, W),
    "status_return_level": (16, 1, 2, W),
    "alarm_led": (17, 1, 36, W),
    "shutdown": (18, 1, 36, W),
    "torque_enable": (24, 1, 0, W),
    "led": (25, 1, 0, W),
    "goal_position": (30, 2, 2048, W),
    "moving_speed": (32, 2, 0, W),
    "torque_limit": (34, 2, 1023, W),
    "present_position": (36, 2, 2048, R),
    "present_speed": (38, 2, 0, R),
    "present_load": (40, 2, 0, R),
    "present_voltage": (42, 1, 120, R),
    "present_temperature": (43, 1, 30, R),
    "registered": (44, 1, 0, R),
    "moving": (46, 1, 0, R),
    "lock": (47, 1, 0, W),
    "punch": (48, 2, 32, W),
}

MX_SERIES_V1 = _table(
    1.0,
    False,
    ("moving_speed", 0.114),
    {
        **_V1_COMMON,
        "multi_turn_offset": (20, 2, 0, W),
        "resolution_divider": (22, 1, 1, W),
        "d_gain": (26, 1, 0, W),
        "i_gain": (27, 1, 0, W),
        "p_gain": (28, 1, 32, W),
        "goal_acceleration": (73, 1, 0, W),
    },
)

AX_SERIES = _table(
    1.0,
    False,
    ("moving_speed", 0.111),
    {
        **_V1_COMMON,
        "ccw_angle_limit": (8, 2, 1023, W),
        "temperature_limit": (11, 1, 70, W),
        "max_voltage_limit": (13, 1, 140, W),
        "cw_compliance_margin": (26, 1, 1, W),
        "ccw_compliance_margin": (27, 1, 1, W),
        "cw_compliance_slope": (28, 1, 32, W),
        "ccw_compliance_slope": (29, 1, 32, W),
        "goal_position": (30, 2, 512, W),
        "present_position": (36, 2, 512, R),
    },
)


@dataclass(frozen=True)
class Model:
    """A servo model on one protocol."""

    name: str
    number: int
    table: ControlTable
    max_position: int = 4095
    """Top of the encoder range, ticks."""
    firmware: int = 45
    no_load_rpm: float = 46.0
    """Top speed of the shaft without load at 12 V (e-Manual), revolutions per minute."""
    ticks_per_rev: float = 4096.0
    """Encoder ticks per turn of the shaft (AX/RX: 1024 per 300 degrees)."""

    @property
    def max_speed(self) -> float:
        """Top speed of the shaft, radians per second."""
        return self.no_load_rpm * _RPM


_AX_TICKS = 1024 * 360 / 300

MODELS: tuple[Model, ...] = (
    Model("XM430-W350", 1020, X_SERIES),
    Model("XM430-W210", 1030, X_SERIES, no_load_rpm=77.0),
    Model("XH430-W350", 1010, X_SERIES),
    Model("XH430-W210", 1000, X_SERIES, no_load_rpm=84.0),
    Model("XM540-W270", 1120, X_SERIES, no_load_rpm=39.0),
    Model("MX-28", 30, X_SERIES, no_load_rpm=55.0),
    Model("MX-64", 311, X_SERIES, no_load_rpm=63.0),
    Model("MX-106", 321, X_SERIES, no_load_rpm=45.0),
    Model("MX-28", 29, MX_SERIES_V1, firmware=41, no_load_rpm=55.0),
    Model("MX-64", 310, MX_SERIES_V1, firmware=41, no_load_rpm=63.0),
    Model("MX-106", 320, MX_SERIES_V1, firmware=41, no_load_rpm=45.0),
    Model(
        "AX-12A",
        12,
        AX_SERIES,
        max_position=1023,
        firmware=24,
        no_load_rpm=59.0,
        ticks_per_rev=_AX_TICKS,
    ),
    Model(
        "AX-18A",
        18,
        AX_SERIES,
        max_position=1023,
        firmware=24,
        no_load_rpm=97.0,
        ticks_per_rev=_AX_TICKS,
    ),
    Model(
        "RX-28",
        28,
        AX_SERIES,
        max_position=1023,
        firmware=24,
        no_load_rpm=67.0,
        ticks_per_rev=_AX_TICKS,
    ),
)
_ALIASES = {"AX-12": "AX-12A", "AX-18": "AX-18A"}


def _key(name: str) -> str:
    name = name.strip().upper()
    return _ALIASES.get(name, name)


MODEL_NAMES: tuple[str, ...] = tuple(sorted({m.name for m in MODELS}))


def find_model(name: str, protocol: float) -> Model:
    """The model called ``name`` (case-insensitive) on ``protocol``; ValueError if unknown."""
    key = _key(name)
    known = [m for m in MODELS if m.name == key]
    if not known:
        raise ValueError(f"unknown servo model {name!r}; expected one of: {', '.join(MODEL_NAMES)}")
    for model in known:
        if model.table.protocol == protocol:
            return model
    speaks = " or ".join(sorted({str(m.table.protocol) for m in known}))
    raise ValueError(f"servo model {name!r} speaks Protocol {speaks}, not {protocol}")


def is_known_model(name: str) -> bool:
    """Whether ``name`` is a servo model of any protocol."""
    return any(m.name == _key(name) for m in MODELS)


HARDWARE_ERRORS2 = {
    0x01: "input voltage",
    0x04: "overheating",
    0x08: "motor encoder",
    0x10: "electrical shock",
    0x20: "overload",
}
"""Bits of the Protocol 2.0 Hardware Error Status register."""

# By member name: a flag's ``.name`` is typed optional (a combination of bits has none).
STATUS_ERRORS1 = {int(e): name.lower().replace("_", " ") for name, e in Error1.__members__.items()}
"""Bits of a Protocol 1.0 status packet's error byte."""


def error_words(bits: int, protocol: float) -> list[str]:
    """The hardware error bits in words; unknown bits as ``bit N``."""
    names = STATUS_ERRORS1 if protocol == 1.0 else HARDWARE_ERRORS2
    return [names.get(1 << n, f"bit {n}") for n in range(8) if bits & (1 << n)]
