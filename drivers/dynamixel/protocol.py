"""Dynamixel packets, byte for byte: Protocol 1.0 (checksum) and 2.0 (CRC16, byte stuffing).

Pure functions used by the emulator (and fuzzed by the tests). Layouts::

    1.0  FF FF ID LEN INST|ERR PARAMS... CHECKSUM           LEN = len(PARAMS) + 2
    2.0  FF FF FD 00 ID LEN_L LEN_H INST [ERR] PARAMS... CRC_L CRC_H
         LEN = stuffed(INST [ERR] PARAMS) + 2; status packets have INST = 0x55 and an error byte

Decoding raises only :class:`PacketError`; :func:`split_frame` never raises.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from percept.drivers.dynamixel.errors import PacketError

BROADCAST_ID = 0xFE
HEADER1 = b"\xff\xff"
HEADER2 = b"\xff\xff\xfd\x00"
# Longest packets accepted when framing a stream (the SDK's RXPACKET_MAX_LEN for 2.0).
MAX_LENGTH1 = 0xFD
MAX_LENGTH2 = 1024
_STUFF_PATTERN = b"\xff\xff\xfd"


class Instruction(enum.IntEnum):
    """Instruction codes (REBOOT and the sync/bulk reads other than 1.0 BULK_READ are 2.0 only)."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class Result(enum.IntEnum):
    """Protocol 2.0 status error numbers (the low 7 bits of a status packet's error byte)."""

    OK = 0
    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7


ALERT = 0x80
"""Protocol 2.0 status error bit: the servo has a hardware error (see Hardware Error Status)."""


class Error1(enum.IntFlag):
    """Protocol 1.0 status error bits."""

    INPUT_VOLTAGE = 0x01
    ANGLE_LIMIT = 0x02
    OVERHEATING = 0x04
    RANGE = 0x08
    CHECKSUM = 0x10
    OVERLOAD = 0x20
    INSTRUCTION = 0x40


@dataclass(frozen=True)
class Packet:
    """An instruction packet (``error`` is None) or a status packet (``error`` is the error byte;
    2.0 status packets carry instruction 0x55, 1.0 ones none, shown here as STATUS too)."""

    id: int
    instruction: int
    params: bytes = b""
    error: int | None = None


def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """CRC-16 (polynomial 0x8005, initial 0, no reflection) as Protocol 2.0 uses it."""
    crc = 0
    for byte in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def checksum(data: bytes) -> int:
    """Protocol 1.0 checksum of the bytes from ID to the last parameter."""
    return ~sum(data) & 0xFF


def stuff(body: bytes) -> bytes:
    """Protocol 2.0 byte stuffing: an FD after FF FF FD in the body so it cannot look like a
    header."""
    out = bytearray()
    for i, byte in enumerate(body):
        out.append(byte)
        if byte == 0xFD and body[max(0, i - 2) : i + 1] == _STUFF_PATTERN:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """Undo :func:`stuff`; an unstuffed FF FF FD inside a body is an error."""
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if body[i] == 0xFD and body[max(0, i - 2) : i + 1] == _STUFF_PATTERN:
            if body[i + 1 : i + 2] != b"\xfd":
                raise PacketError("header pattern FF FF FD inside a packet without stuffing")
            i += 1
        i += 1
    return bytes(out)


def _check_id(servo_id: int) -> None:
    if not 0 <= servo_id <= BROADCAST_ID:
        raise ValueError(f"servo id {servo_id} is outside 0-254")


def encode(protocol: float, packet: Packet) -> bytes:
    """The bytes of ``packet`` on the wire."""
    _check_id(packet.id)
    if protocol == 1.0:
        first = packet.instruction if packet.error is None else packet.error
        body = bytes([packet.id, len(packet.params) + 2, first]) + packet.params
        return HEADER1 + body + bytes([checksum(body)])
    if packet.error is None:
        inner = bytes([packet.instruction])
    else:
        inner = bytes([Instruction.STATUS, packet.error])
    body = stuff(inner + packet.params)
    length = len(body) + 2
    head = HEADER2 + bytes([packet.id, length & 0xFF, length >> 8])
    crc = crc16(head + body)
    return head + body + bytes([crc & 0xFF, crc >> 8])


def decode(protocol: float, frame: bytes, *, status: bool) -> Packet:
    """Parse exactly one packet; ``status`` says whether it is a reply (has an error byte)."""
    if protocol == 1.0:
        return _decode1(frame, status)
    return _decode2(frame, status)


def _decode1(frame: bytes, status: bool) -> Packet:
    if len(frame) < 6 or frame[:2] != HEADER1:
        raise PacketError(f"not a Protocol 1.0 packet: {frame[:6].hex(' ')}")
    servo_id, length = frame[2], frame[3]
    if servo_id == 0xFF:
        raise PacketError("id 0xFF is not allowed")
    if len(frame) != length + 4:
        raise PacketError(f"length field says {length + 4} bytes, packet has {len(frame)}")
    if checksum(frame[2:-1]) != frame[-1]:
        raise PacketError(f"checksum {frame[-1]:#04x}, expected {checksum(frame[2:-1]):#04x}")
    first, params = frame[4], bytes(frame[5:-1])
    if status:
        return Packet(servo_id, Instruction.STATUS, params, error=first)
    return Packet(servo_id, first, params)


def _decode2(frame: bytes, status: bool) -> Packet:
    if len(frame) < 10 or frame[:4] != HEADER2:
        raise PacketError(f"not a Protocol 2.0 packet: {frame[:10].hex(' ')}")
    servo_id, length = frame[4], frame[5] | frame[6] << 8
    if servo_id == 0xFF:
        raise PacketError("id 0xFF is not allowed")
    if len(frame) != length + 7:
        raise PacketError(f"length field says {length + 7} bytes, packet has {len(frame)}")
    crc = frame[-2] | frame[-1] << 8
    if crc16(frame[:-2]) != crc:
        raise PacketError(f"CRC {crc:#06x}, expected {crc16(frame[:-2]):#06x}")
    body = unstuff(frame[7:-2])
    if status:
        if len(body) < 2 or body[0] != Instruction.STATUS:
            raise PacketError(f"not a status packet: instruction {body[0]:#04x}")
        return Packet(servo_id, Instruction.STATUS, bytes(body[2:]), error=body[1])
    return Packet(servo_id, body[0], bytes(body[1:]))


def split_frame(protocol: float, buffer: bytes) -> tuple[bytes | None, bytes]:
    """Cut the first complete packet out of a byte stream: ``(frame, rest)``.

    Bytes before a header are dropped; ``(None, rest)`` means wait for more bytes. A header with
    an impossible length is skipped, so garbage never blocks the stream.
    """
    if protocol == 1.0:
        header, fixed, id_at, shortest, longest = HEADER1, 4, 2, 2, MAX_LENGTH1
    else:
        header, fixed, id_at, shortest, longest = HEADER2, 7, 4, 3, MAX_LENGTH2
    while True:
        start = buffer.find(header)
        if start < 0:
            # Keep a possible partial header at the end.
            keep = next(
                (n for n in range(len(header) - 1, 0, -1) if buffer.endswith(header[:n])), 0
            )
            return None, buffer[len(buffer) - keep :] if keep else b""
        buffer = buffer[start:]
        if len(buffer) < fixed:
            return None, buffer
        length = buffer[3] if protocol == 1.0 else buffer[5] | buffer[6] << 8
        if buffer[id_at] == 0xFF or not shortest <= length <= longest:
            buffer = buffer[1:]
            continue
        total = fixed + length
        if len(buffer) < total:
            return None, buffer
        return bytes(buffer[:total]), buffer[total:]
