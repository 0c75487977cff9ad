"""One open connection to a Dynamixel bus through dynamixel-sdk, with the SDK's traps guarded.

The SDK is used as is, behind a thin seam (:class:`ExclusivePort`, a ``PortHandler``):

- the port is opened exclusively (another percept or a forgotten script fails to open it),
- the packet timeout is ours (``BusSettings.timeout``), not the SDK's fixed 2 x 16 ms latency
  constant, and measured on the monotonic clock rather than ``time.time()``,
- waiting for a reply sleeps in ``select`` instead of the SDK's busy loop,
- serial failures (USB unplugged) surface as :class:`PortLost` (the SDK's ``is_using`` flag is
  then left set, so a lost link is dropped and the port reopened, never reused).

:class:`Link` adds the checks the SDK leaves to its caller: a failed or partial sync read yields
no values (``getData`` would say 0), every reply must carry exactly the requested length, and
every read returns the status packets' error bytes (which the SDK's sync read drops). Writes
go out as the SDK builds them: a single write waits for its status packet (an error byte there
fails it), a sync write (GroupSyncWrite) is a broadcast that no servo answers.
"""

from __future__ import annotations

import errno
import select
import termios
import time
from collections.abc import Sequence
from typing import Protocol

import dynamixel_sdk as sdk
import serial

from percept.drivers.dynamixel.errors import PortLost, PortUnavailable, ReadFailed, WriteFailed
from percept.drivers.dynamixel.protocol import Error1

# Errors that waiting will not fix: a person must change permissions or the configured path.
_NEEDS_A_PERSON = {errno.EACCES, errno.EPERM, errno.ENOTTY, errno.EISDIR}
# What a vanished device raises (pyserial's SerialException is an OSError; tcflush raises
# termios.error).
_PORT_ERRORS = (OSError, termios.error)
# Status error bits that say a write was refused (the others report hardware errors, which
# the bus polls for itself): 2.0 all but the alert bit, 1.0 range, checksum, instruction and
# angle limit.
_REFUSALS = {
    2.0: 0x7F,
    1.0: Error1.RANGE | Error1.CHECKSUM | Error1.INSTRUCTION | Error1.ANGLE_LIMIT,
}
# Longest sleep while waiting for reply bytes; short enough not to add latency.
_POLL_S = 0.002


class ExclusivePort(sdk.PortHandler):
    """The SDK's port handler with an exclusive open, our timeout and no busy waiting."""

    # Set by the SDK's constructor and by the open/close overrides below; declared here because
    # the untyped SDK base class gives mypy no type for it.
    is_open: bool

    def __init__(self, port_name: str, timeout_s: float) -> None:
        super().__init__(port_name)
        self.timeout_ms = timeout_s * 1000.0

    def setupPort(self, cflag_baud: int) -> bool:
        if self.is_open:
            self.closePort()
        try:
            self.ser = serial.Serial(
                port=self.port_name,
                baudrate=self.baudrate,
                bytesize=serial.EIGHTBITS,
                timeout=0,
                exclusive=True,
            )
        except (*_PORT_ERRORS, ValueError) as err:
            code = getattr(err, "errno", None)
            raise PortUnavailable(
                self.port_name, _reason(err), fixable_by_waiting=code not in _NEEDS_A_PERSON
            ) from err
        self.is_open = True
        self.ser.reset_input_buffer()
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True

    def setPacketTimeout(self, packet_length: int) -> None:
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.timeout_ms

    def getCurrentTime(self) -> float:
        return time.monotonic() * 1000.0

    def readPort(self, length: int) -> bytes:
        try:
            if not self.ser.in_waiting:
                left_ms = self.packet_timeout - self.getTimeSinceStart()
                if left_ms > 0:
                    select.select([self.ser.fileno()], [], [], min(left_ms / 1000.0, _POLL_S))
            return self.ser.read(length)
        except _PORT_ERRORS as err:
            raise PortLost(f"{self.port_name}: {_reason(err)}") from err

    def writePort(self, packet: Sequence[int]) -> int:
        try:
            return self.ser.write(bytes(packet))
        except _PORT_ERRORS as err:
            raise PortLost(f"{self.port_name}: {_reason(err)}") from err

    def clearPort(self) -> None:
        try:
            self.ser.reset_input_buffer()
        except _PORT_ERRORS as err:
            raise PortLost(f"{self.port_name}: {_reason(err)}") from err

    def closePort(self) -> None:
        try:
            if self.ser is not None:
                self.ser.close()
        except _PORT_ERRORS:
            pass  # closing a vanished device may fail; it is closed either way
        self.is_open = False


def _reason(err: BaseException) -> str:
    strerror = getattr(err, "strerror", None)
    return strerror or str(err) or type(err).__name__


class _ResultNames(Protocol):
    """The part of the SDK's (untyped) packet handlers that names a communication result."""

    def getTxRxResult(self, result: int) -> str: ...


def _comm(ph: _ResultNames, result: int) -> str:
    return ph.getTxRxResult(result).removeprefix("[TxRxResult] ")


class Link:
    """An open bus: reads and writes registers of servos, raising :class:`ReadFailed`,
    :class:`WriteFailed` or :class:`PortLost`."""

    def __init__(self, port: str, baudrate: int, protocol: float, timeout_s: float) -> None:
        self.protocol = protocol
        self.port = ExclusivePort(port, timeout_s)
        self.ph = sdk.PacketHandler(protocol)
        if not self.port.setBaudRate(baudrate):
            raise PortUnavailable(
                port, f"baud rate {baudrate} is not supported", fixable_by_waiting=False
            )
        self._groups: dict[tuple[tuple[int, ...], int, int], sdk.GroupSyncRead] = {}

    def close(self) -> None:
        self.port.closePort()

    def read(self, servo_id: int, address: int, size: int) -> tuple[bytes, int]:
        """(register bytes, status error byte) of one servo."""
        if self.protocol == 1.0:
            tx = [0, 0, servo_id, 4, sdk.INST_READ, address, size, 0]
        else:
            tx = [0] * 14
            tx[4:8] = [servo_id, 7, 0, sdk.INST_READ]
            tx[8:12] = [address & 0xFF, address >> 8, size & 0xFF, size >> 8]
        rx, result, error = self.ph.txRxPacket(self.port, tx)
        if result != sdk.COMM_SUCCESS:
            raise ReadFailed(servo_id, _comm(self.ph, result))
        return self._payload(rx, servo_id, size), error

    def sync_read(
        self, ids: Sequence[int], address: int, size: int
    ) -> dict[int, tuple[bytes, int]]:
        """Protocol 2.0 sync read of one register range from several servos, all or nothing:
        (register bytes, status error byte) by servo id.

        GroupSyncRead sends the request; the replies are taken here, one status packet per
        servo, because the SDK's own collection cannot tell a reply of the wrong length and,
        after a failure, has getData answer 0 for every servo.
        """
        key = (tuple(ids), address, size)
        group = self._groups.get(key)
        if group is None:
            group = self._groups[key] = sdk.GroupSyncRead(self.port, self.ph, address, size)
            for servo_id in ids:
                group.addParam(servo_id)
        result = group.txPacket()
        if result != sdk.COMM_SUCCESS:
            raise ReadFailed(None, _comm(self.ph, result))
        out: dict[int, tuple[bytes, int]] = {}
        for servo_id in ids:
            while True:  # skip replies of other servos, as the SDK does
                rx, result = self.ph.rxPacket(self.port, False)
                if result != sdk.COMM_SUCCESS:
                    raise ReadFailed(servo_id, _comm(self.ph, result))
                if rx[4] == servo_id:
                    break
            out[servo_id] = self._payload(rx, servo_id, size), rx[8]
        return out

    def write(self, servo_id: int, address: int, data: bytes) -> None:
        """Write ``data`` at ``address`` of one servo and wait for its acknowledgement."""
        result, error = self.ph.writeTxRx(self.port, servo_id, address, len(data), list(data))
        if result != sdk.COMM_SUCCESS:
            raise WriteFailed(servo_id, _comm(self.ph, result))
        if error & _REFUSALS[self.protocol]:
            reason = str(self.ph.getRxPacketError(error)).removeprefix("[RxPacketError] ")
            raise WriteFailed(servo_id, f"refused: {reason}")

    def sync_write(self, address: int, size: int, data: dict[int, bytes]) -> None:
        """One SYNC WRITE of ``size`` bytes at ``address`` to several servos (no replies)."""
        group = sdk.GroupSyncWrite(self.port, self.ph, address, size)
        for servo_id, values in data.items():
            if len(values) != size or not group.addParam(servo_id, list(values)):
                raise ValueError(f"servo {servo_id}: {len(values)} bytes to write, not {size}")
        result = group.txPacket()
        if result != sdk.COMM_SUCCESS:
            raise WriteFailed(None, _comm(self.ph, result))

    def _payload(self, rx: Sequence[int], servo_id: int, size: int) -> bytes:
        """The parameters of a status packet that must carry exactly ``size`` bytes.

        Replies carry no sequence number: a reply arriving after its read timed out is taken
        by the SDK as the answer to the next read of that servo, and sliced to the size asked
        for. Reads of different lengths make such replies visible here.
        """
        if self.protocol == 1.0:
            got, at = rx[3] - 2, 5
        else:
            got, at = (rx[5] | rx[6] << 8) - 4, 9
        if got != size:
            raise ReadFailed(servo_id, f"reply carries {got} bytes, asked for {size}")
        return bytes(rx[at : at + size])
