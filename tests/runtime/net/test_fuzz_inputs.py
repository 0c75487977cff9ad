"""Property-based tests that reach past the first checks of each parser: no input makes the
message decoder, the Dynamixel packet parser (and the emulator's handling of instruction packets)
or the config loader fail with anything but the project's own error types.

Random bytes rarely get past a parser's first check (a JSON object, a packet header and CRC), so
these generate inputs that do: valid messages with one part changed, packets with a correct
header and CRC/checksum around any body, and the shipped scene files with one part changed
(tests/test_fuzz_config.py does the same for profiles and experiments).
"""

from __future__ import annotations

import copy
import json
import time
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from percept.config.loader import ConfigError, build
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.errors import PacketError
from percept.drivers.dynamixel.protocol import Packet, checksum, crc16, decode, encode, split_frame
from percept.drivers.dynamixel.settings import JointSettings
from percept.drivers.sim.scene import Scene
from percept.runtime.net.messages import MessageError
from percept.runtime.net.messages import decode as decode_message
from percept.runtime.net.messages import encode as encode_message
from tests.support.fuzz import fuzz_settings, mutate, paths, values
from tests.support.messages import MESSAGES

REPO = Path(__file__).resolve().parents[3]
FUZZ = fuzz_settings(300)
PROTOCOLS = (1.0, 2.0)

_JSON = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.integers(-(2**70), 2**70)
    | st.floats()
    | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=10,
)
DOCS = [{"schema": m.SCHEMA, **json.loads(json.dumps(m.to_json()))} for m in MESSAGES]


def _places(node: Any, path: tuple = ()) -> list[tuple]:
    """Every key of every object and index of every list in a JSON document."""
    items = node.items() if isinstance(node, dict) else enumerate(node)
    out = []
    for key, child in items:
        out.append((*path, key))
        if isinstance(child, dict | list):
            out.extend(_places(child, (*path, key)))
    return out


@FUZZ
@given(data=st.data())
def test_messages_with_one_part_changed_decode_or_raise_message_error(data: st.DataObject) -> None:
    doc = copy.deepcopy(data.draw(st.sampled_from(DOCS)))
    path = data.draw(st.sampled_from(_places(doc)))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    action, value = data.draw(st.sampled_from(["replace", "remove", "add"])), data.draw(_JSON)
    if action == "replace":
        parent[path[-1]] = value
    elif action == "remove":
        del parent[path[-1]]
    elif isinstance(parent, dict):
        parent[f"extra_{path[-1]}"] = value
    else:
        parent.insert(path[-1], value)
    payload = json.dumps(doc).encode()  # NaN and Infinity as JSON has them: refused on receipt
    try:
        message = decode_message(payload)
    except MessageError:
        return
    assert decode_message(encode_message(message)) == message


def _framed(protocol: float, servo_id: int, body: bytes, length_error: int) -> bytes:
    """A packet with a valid header and CRC/checksum around ``body`` (the instruction or status
    byte, error and parameters, unchecked), its length field off by ``length_error``."""
    if protocol == 2.0:
        n = max(0, len(body) + 2 + length_error)
        frame = bytes([0xFF, 0xFF, 0xFD, 0x00, servo_id, n & 0xFF, n >> 8]) + body
        crc = crc16(frame)
        return frame + bytes([crc & 0xFF, crc >> 8])
    n = max(0, len(body) + 1 + length_error) & 0xFF
    frame = bytes([0xFF, 0xFF, servo_id, n]) + body
    return frame + bytes([checksum(frame[2:])])


@pytest.mark.parametrize("protocol", PROTOCOLS)
@FUZZ
@given(
    servo_id=st.integers(0, 0xFF),
    body=st.binary(max_size=40),
    length_error=st.sampled_from([0, 0, 0, -2, -1, 1, 2]),
    status=st.booleans(),
)
def test_framed_packets_of_any_content_raise_only_packet_error(
    protocol: float, servo_id: int, body: bytes, length_error: int, status: bool
) -> None:
    frame = _framed(protocol, servo_id, body, length_error)
    try:
        packet = decode(protocol, frame, status=status)
    except PacketError:
        packet = None
    found, rest = split_frame(protocol, frame + b"\x00\x01")
    if packet is not None:  # what decodes is found whole in a stream
        assert found == frame and rest == b"\x00\x01"


@pytest.fixture(scope="module")
def emulators() -> dict[float, ServoEmulator]:
    """Emulators whose packet handling is called directly (no pty needed)."""
    x = [JointSettings("a", 1, "XM430-W350"), JointSettings("b", 2, "XM430-W350")]
    mx = [
        JointSettings("a", 1, "MX-28"),
        JointSettings("b", 2, "AX-12A", ticks_per_rev=1228.8, zero_tick=512),
    ]
    return {2.0: ServoEmulator(x, 2.0), 1.0: ServoEmulator(mx, 1.0)}


@pytest.mark.parametrize("protocol", PROTOCOLS)
@FUZZ
@given(
    servo_id=st.sampled_from([0, 1, 2, 7, 0xFD, 0xFE]),
    instruction=st.integers(0, 0xFF),
    params=st.binary(max_size=24),
)
def test_emulator_answers_any_instruction_packet_without_failing(
    protocol: float,
    servo_id: int,
    instruction: int,
    params: bytes,
    emulators: dict[float, ServoEmulator],
) -> None:
    emulator = emulators[protocol]
    frame = encode(protocol, Packet(servo_id, instruction, params))
    emulator._on_frame(frame, time.monotonic())  # an exception here would end its thread
    emulator._outbox.clear()
    emulator._on_frame(_framed(protocol, servo_id, bytes([instruction]) + params, 1), 0.0)


SCENES = sorted((REPO / "config" / "scenes").glob("*.toml"))


@pytest.mark.parametrize("file", SCENES, ids=[p.name for p in SCENES])
@settings(max_examples=40, deadline=None, database=None)
@given(data=st.data())
def test_shipped_scenes_with_one_part_changed(file: Path, data: st.DataObject) -> None:
    doc = tomllib.loads(file.read_text(encoding="utf-8"))
    path = data.draw(st.sampled_from(paths(doc)))
    action = data.draw(st.sampled_from(["replace", "remove", "add"]))
    try:
        scene = build(Scene, mutate(doc, path, action, data.draw(values)), file)
    except ConfigError as err:
        assert str(err).startswith(str(file))
    else:
        assert isinstance(scene, Scene)
