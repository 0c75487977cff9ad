"""Errors of the Dynamixel driver, its packet codec and its emulator."""

from __future__ import annotations


class DynamixelError(Exception):
    """Something went wrong talking to Dynamixel servos."""


class PacketError(DynamixelError):
    """Bytes that are not a valid Dynamixel packet (bad header, length, CRC or checksum)."""


class PortUnavailable(DynamixelError):
    """The serial port cannot be opened: missing, in use by another program, or not permitted."""

    def __init__(self, port: str, reason: str, *, fixable_by_waiting: bool = True) -> None:
        self.port = port
        self.reason = reason
        # Permission problems and non-serial devices need a person; a missing or busy port may
        # come back on its own.
        self.fixable_by_waiting = fixable_by_waiting
        super().__init__(f"cannot open {port}: {reason}")


class PortLost(DynamixelError):
    """An open serial port failed (USB unplugged, emulator gone)."""


class ReadFailed(DynamixelError):
    """A read got no valid answer: timeout, corrupt or short reply."""

    def __init__(self, servo_id: int | None, reason: str) -> None:
        self.servo_id = servo_id
        self.reason = reason
        who = "sync read" if servo_id is None else f"servo {servo_id}"
        super().__init__(f"{who}: {reason}")


class WriteFailed(DynamixelError):
    """A write was not sent, not acknowledged, or refused by the servo."""

    def __init__(self, servo_id: int | None, reason: str) -> None:
        self.servo_id = servo_id
        self.reason = reason
        who = "sync write" if servo_id is None else f"servo {servo_id}"
        super().__init__(f"{who}: {reason}")
