"""The Dynamixel packet codec against published packets and against dynamixel-sdk's own code, plus
property tests: round trips, and garbage that never raises anything but PacketError."""

from __future__ import annotations

import contextlib
import math

import dynamixel_sdk as sdk
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from percept.config.loader import ConfigError, build
from percept.drivers.dynamixel.bus import radians_to_ticks, ticks_to_radians
from percept.drivers.dynamixel.errors import PacketError
from percept.drivers.dynamixel.models import MODELS, error_words, find_model
from percept.drivers.dynamixel.protocol import (
    Instruction,
    Packet,
    checksum,
    crc16,
    decode,
    encode,
    split_frame,
    stuff,
    unstuff,
)
from percept.drivers.dynamixel.settings import BusSettings, JointSettings

PROTOCOLS = [1.0, 2.0]
ids = st.integers(0, 0xFE)
params = st.binary(max_size=40)
# Bodies rich in the bytes that need stuffing.
stuffy = st.lists(st.sampled_from([0xFF, 0xFD, 0x00, 0x55]), max_size=30).map(bytes)


def test_published_packets() -> None:
    """Examples from the ROBOTIS e-Manual (Protocol 2.0 and 1.0 instruction packets)."""
    assert encode(2.0, Packet(1, Instruction.PING)).hex(" ") == "ff ff fd 00 01 03 00 01 19 4e"
    read = Packet(1, Instruction.READ, bytes([0x84, 0x00, 0x04, 0x00]))
    assert encode(2.0, read).hex(" ") == "ff ff fd 00 01 07 00 02 84 00 04 00 1d 15"
    assert encode(1.0, Packet(1, Instruction.PING)).hex(" ") == "ff ff 01 02 01 fb"
    # 1.0 READ of present position (36, 2 bytes) from id 1: FF FF 01 04 02 24 02 D2
    read1 = Packet(1, Instruction.READ, bytes([36, 2]))
    assert encode(1.0, read1).hex(" ") == "ff ff 01 04 02 24 02 d2"


@given(st.binary(max_size=300))
def test_crc_matches_the_sdk(data: bytes) -> None:
    assert crc16(data) == sdk.Protocol2PacketHandler().updateCRC(0, list(data), len(data))


@given(ids, st.sampled_from(list(Instruction)), stuffy | params)
def test_stuffed_packets_match_the_sdk(servo_id: int, instruction: int, body: bytes) -> None:
    """The SDK builds the same bytes for the same instruction packet (stuffing, length, CRC)."""
    ph = sdk.Protocol2PacketHandler()
    raw = [0xFF, 0xFF, 0xFD, 0x00, servo_id, 0, 0, instruction, *body, 0, 0]
    length = len(body) + 3
    raw[5], raw[6] = length & 0xFF, length >> 8
    stuffed = ph.addStuffing(raw)
    total = (stuffed[5] | stuffed[6] << 8) + 7
    crc = ph.updateCRC(0, stuffed, total - 2)
    expected = bytes(stuffed[: total - 2]) + bytes([crc & 0xFF, crc >> 8])
    assert encode(2.0, Packet(servo_id, instruction, body)) == expected


@given(stuffy | params)
def test_stuffing_round_trip(body: bytes) -> None:
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    # After stuffing, every FF FF FD is followed by FD: no header can appear inside a packet.
    for i in range(len(stuffed) - 2):
        if stuffed[i : i + 3] == b"\xff\xff\xfd":
            assert stuffed[i + 3 : i + 4] == b"\xfd"


@pytest.mark.parametrize("protocol", PROTOCOLS)
@given(servo_id=ids, instruction=st.integers(0, 0xFF), body=stuffy | params)
def test_instruction_round_trip(
    protocol: float, servo_id: int, instruction: int, body: bytes
) -> None:
    packet = Packet(servo_id, instruction, body)
    frame = encode(protocol, packet)
    assert decode(protocol, frame, status=False) == packet
    assert split_frame(protocol, b"\x00\x12" + frame + b"\xff") == (frame, b"\xff")


@pytest.mark.parametrize("protocol", PROTOCOLS)
@given(servo_id=ids, error=st.integers(0, 0xFF), body=stuffy | params)
def test_status_round_trip(protocol: float, servo_id: int, error: int, body: bytes) -> None:
    packet = Packet(servo_id, Instruction.STATUS, body, error=error)
    assert decode(protocol, encode(protocol, packet), status=True) == packet


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_damaged_packets_are_refused(protocol: float) -> None:
    frame = encode(protocol, Packet(7, Instruction.STATUS, b"\x10\x08", error=0))
    bad_crc = frame[:-1] + bytes([frame[-1] ^ 0xFF])
    with pytest.raises(PacketError, match=r"CRC|checksum"):
        decode(protocol, bad_crc, status=True)
    with pytest.raises(PacketError, match="length"):
        decode(protocol, frame[:-1] + frame[-1:] * 2, status=True)
    with pytest.raises(PacketError):
        decode(protocol, frame[:-3], status=True)
    # A stream with a short packet waits for more bytes rather than inventing one.
    assert split_frame(protocol, frame[:-3]) == (None, frame[:-3])


@pytest.mark.parametrize("protocol", PROTOCOLS)
@settings(max_examples=300)
@given(data=st.binary(max_size=80), status=st.booleans())
def test_garbage_raises_only_packet_error(protocol: float, data: bytes, status: bool) -> None:
    with contextlib.suppress(PacketError):
        decode(protocol, data, status=status)
    frame, rest = split_frame(protocol, data)
    assert frame is None or data.find(frame) >= 0
    assert len(rest) <= len(data)


@pytest.mark.parametrize("protocol", PROTOCOLS)
@given(
    packets=st.lists(st.tuples(ids, st.integers(0, 0xFF), params), min_size=1, max_size=4),
    junk=st.lists(st.binary(max_size=6).filter(lambda b: 0xFF not in b), min_size=5, max_size=5),
)
def test_stream_recovers_every_packet_between_junk(
    protocol: float, packets: list[tuple[int, int, bytes]], junk: list[bytes]
) -> None:
    frames = [encode(protocol, Packet(i, ins, p)) for i, ins, p in packets]
    stream = b"".join(j + f for j, f in zip(junk, frames, strict=False)) + junk[-1]
    found = []
    while True:
        frame, stream = split_frame(protocol, stream)
        if frame is None:
            break
        found.append(frame)
    assert found == frames


def test_checksum() -> None:
    assert checksum(bytes([1, 2, 1])) == 0xFB


def test_models_and_errors() -> None:
    assert find_model("XM430-W350", 2.0).number == 1020
    assert find_model("mx-28", 1.0).number == 29
    assert find_model("AX-12", 1.0).name == "AX-12A"
    with pytest.raises(ValueError, match=r"speaks Protocol 1\.0, not 2\.0"):
        find_model("AX-12A", 2.0)
    with pytest.raises(ValueError, match="unknown servo model 'XL-9000'"):
        find_model("XL-9000", 2.0)
    assert error_words(0x24, 2.0) == ["overheating", "overload"]
    assert error_words(0x41, 1.0) == ["input voltage", "instruction"]
    for model in MODELS:
        table = model.table
        assert table["present_position"].address == (132 if table.protocol == 2.0 else 36)
        assert table["model_number"].address == 0


@given(
    ticks=st.integers(0, 4095),
    zero=st.integers(0, 4095),
    sign=st.sampled_from([-1, 1]),
    per_rev=st.sampled_from([4096.0, 1228.8]),
)
def test_ticks_radians_round_trip(ticks: int, zero: int, sign: int, per_rev: float) -> None:
    joint = JointSettings("j", 1, ticks_per_rev=per_rev, zero_tick=zero, sign=sign)
    angle = ticks_to_radians(ticks, joint)
    assert radians_to_ticks(angle, joint) == ticks
    assert math.isclose(angle, sign * (ticks - zero) * 2 * math.pi / per_rev)


def test_bus_and_joint_settings_are_checked() -> None:
    with pytest.raises(ConfigError) as err:
        build(BusSettings, {"rate": 10.0}, "robot.toml", "bus")
    assert str(err.value) == (
        "robot.toml: bus: stale_after (0.1 s) must be at least two read periods (0.2 s at rate 10)"
    )
    with pytest.raises(ConfigError) as err:
        build(BusSettings, {"reconnect_backoff": [3.0, 1.0]}, "robot.toml", "bus")
    assert str(err.value) == (
        "robot.toml: bus: reconnect_backoff: expected 0 < first <= largest, got [3.0, 1.0]"
    )
    # A first wait of 0 would spin the reconnect loop while the port is missing.
    with pytest.raises(ConfigError) as err:
        build(BusSettings, {"reconnect_backoff": [0.0, 1.0]}, "robot.toml", "bus")
    assert str(err.value) == (
        "robot.toml: bus: reconnect_backoff: expected 0 < first <= largest, got [0.0, 1.0]"
    )
    with pytest.raises(ConfigError) as err:
        build(
            JointSettings, {"name": "pan", "id": 1, "model": "XL-9000"}, "robot.toml", "joints[0]"
        )
    assert str(err.value).startswith(
        "robot.toml: joints[0]: unknown servo model 'XL-9000'; expected one of: AX-12A, AX-18A"
    )
