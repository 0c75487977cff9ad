"""A Dynamixel bus on a pseudo-terminal, byte for byte, for tests and runs without a robot.

The emulator answers Protocol 2.0 or 1.0 instruction packets (PING, READ, WRITE, SYNC READ,
SYNC WRITE, BULK READ, REBOOT; 1.0 has no SYNC READ and no REBOOT and answers those with an
instruction error) from servos with the control tables in
:mod:`percept.drivers.dynamixel.models`. Anything that opens :attr:`ServoEmulator.port_path`
with pyserial, dynamixel-sdk included, talks to it as to a USB adapter.

A servo with torque on moves from where it is towards its goal position at a constant speed:
its profile velocity (2.0) or moving speed (1.0), where 0 means as fast as the model goes, and
never faster than the model's no-load speed (nor, on 2.0, its velocity limit). Torque off, it
stays where it is (or where :meth:`ServoEmulator.set_angle` puts it). Positions are brought up
to date whenever they are looked at, so motion needs no thread of its own. The Protocol 2.0
bus watchdog works as on the servos: armed (Bus Watchdog 1-127, in 20 ms, torque on), a bus
silent for longer sets it to 0xFF, holds the servo where it is and refuses goals until it is
written 0.

A recording of joint angles can be played back (:meth:`ServoEmulator.play`): the servos of the
recorded joints then report the recorded angles at their times, from a wall-clock epoch, while
goals are still accepted (and kept, see :meth:`ServoEmulator.goals`) but do not move them: a
recorded run served to a daemon as the servos of a moving head.

Positions can be set while it runs, and faults injected: a mute servo, corrupt CRC/checksum,
short replies, wrong positions in valid replies (a glitching encoder), hardware error bits,
reply delays, and the port vanishing (unplug) and coming back at the same path (a symlink
re-pointed to a fresh pty).
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import logging
import math
import os
import select
import tempfile
import threading
import time
import tty
import uuid
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from percept.drivers.dynamixel.bus import radians_to_ticks, ticks_to_radians
from percept.drivers.dynamixel.errors import PacketError
from percept.drivers.dynamixel.models import Model, find_model
from percept.drivers.dynamixel.playback import JointRecording
from percept.drivers.dynamixel.protocol import (
    ALERT,
    BROADCAST_ID,
    Error1,
    Instruction,
    Packet,
    Result,
    decode,
    encode,
    split_frame,
)
from percept.drivers.dynamixel.settings import WATCHDOG_UNIT, JointSettings

log = logging.getLogger("percept.emulator")

# Baud rate register values: X series (2.0) use a code, MX/AX (1.0) 2 Mbaud / (value + 1).
_BAUD_CODES2 = {9600: 0, 57600: 1, 115200: 2, 1_000_000: 3, 2_000_000: 4, 3_000_000: 5}
_EEPROM_END2 = 64  # X series: EEPROM is writable only with torque off
_GOALS_KEPT = 100_000


def _baud_value(protocol: float, baudrate: int) -> int:
    if protocol == 1.0:
        return max(0, min(254, round(2_000_000 / baudrate) - 1))
    return _BAUD_CODES2.get(baudrate, 3)


@dataclass
class _Faults:
    """Injected misbehaviour of one servo; counts are replies still to spoil (inf: all)."""

    mute: bool = False
    corrupt: float = 0
    short: float = 0
    delay: float = 0.0
    glitch: float = 0  # replies whose present position says ``glitch_ticks``
    glitch_ticks: int = 0


def _take(count: float) -> tuple[bool, float]:
    return (True, count - 1) if count > 0 else (False, count)


class _Servo:
    """One servo: a control table in memory."""

    def __init__(self, servo_id: int, model: Model, baud_value: int) -> None:
        self.model = model
        self.table = model.table
        self.memory = bytearray(self.table.size)
        for name, reg in self.table.registers.items():
            self.put(name, reg.default)
        self.put("model_number", model.number)
        self.put("firmware_version", model.firmware)
        self.put("id", servo_id)
        self.put("baud_rate", baud_value)
        self.faults = _Faults()
        self.status_bits = 0  # Protocol 1.0 hardware error bits of every status packet
        self.goals: list[int] = []  # every goal position taken, oldest first (bounded)
        self.position = float(self.get("present_position"))  # ticks, between whole ticks
        self.moved_at = time.monotonic()  # when position was last brought up to date

    @property
    def id(self) -> int:
        return self.get("id")

    def get(self, name: str) -> int:
        reg = self.table[name]
        raw = self.memory[reg.address : reg.address + reg.size]
        signed = name == "present_position" and self.table.position_signed
        return int.from_bytes(raw, "little", signed=signed)

    def put(self, name: str, value: int) -> None:
        reg = self.table[name]
        self.memory[reg.address : reg.address + reg.size] = value.to_bytes(
            reg.size, "little", signed=value < 0
        )

    def read(self, address: int, size: int) -> bytes | None:
        if size < 1 or address + size > self.table.size:
            return None
        data = bytearray(self.memory[address : address + size])
        if self.touches("present_position", address, size):
            glitch, self.faults.glitch = _take(self.faults.glitch)
            if glitch:  # the encoder says something else; the shaft stays where it is
                reg = self.table["present_position"]
                ticks = self.faults.glitch_ticks
                wrong = ticks.to_bytes(reg.size, "little", signed=ticks < 0)
                for k, byte in enumerate(wrong):
                    if address <= reg.address + k < address + size:
                        data[reg.address + k - address] = byte
        return bytes(data)

    def writable(self, address: int, size: int) -> bool:
        """Whether every register touched by a write of ``size`` bytes at ``address`` is
        writable and wholly inside it."""
        if size < 1 or address + size > self.table.size:
            return False
        end = address + size
        touched = [
            r
            for r in self.table.registers.values()
            if r.address < end and address < r.address + r.size
        ]
        covered = sum(r.size for r in touched)
        return bool(touched) and all(r.writable for r in touched) and covered >= size

    def touches(self, name: str, address: int, size: int) -> bool:
        reg = self.table.registers.get(name)
        return reg is not None and address < reg.address + reg.size and reg.address < address + size

    def write(self, address: int, data: bytes) -> None:
        self.memory[address : address + len(data)] = data
        if self.touches("goal_position", address, len(data)):
            self.goals = [*self.goals[-(_GOALS_KEPT - 1) :], self.get("goal_position")]

    def place(self, ticks: int) -> None:
        """Put the shaft at ``ticks`` (moved by hand, or by the simulated world)."""
        self.position = float(ticks)
        self.put("present_position", ticks)

    def speed(self) -> float:
        """Ticks per second towards the goal: the speed register (0: the top speed), capped."""
        model, table = self.model, self.table
        top = model.max_speed
        if "velocity_limit" in table.registers:
            top = min(top, self.get("velocity_limit") * table.speed_unit)
        asked = self.get(table.speed_register) * table.speed_unit
        radians = min(asked, top) if asked > 0 else top
        return radians * model.ticks_per_rev / (2.0 * math.pi)

    def advance(self, now: float) -> None:
        """Move towards the goal for the time since the last call (torque on only)."""
        if now <= self.moved_at:
            return
        if self.get("torque_enable"):
            goal = self.get("goal_position")
            step = self.speed() * (now - self.moved_at)
            gap = goal - self.position
            self.position = goal if abs(gap) <= step else self.position + math.copysign(step, gap)
            self.put("present_position", round(self.position))
        self.moved_at = now

    def watchdog_deadline(self, silent_since: float) -> float | None:
        """When the armed bus watchdog goes off if the bus stays silent since ``silent_since``."""
        if "bus_watchdog" not in self.table.registers or not self.get("torque_enable"):
            return None
        units = self.get("bus_watchdog")
        return silent_since + units * WATCHDOG_UNIT if 0 < units < 0x80 else None

    def watchdog_off(self) -> None:
        """The watchdog went off: 0xFF, and the servo stops where it is."""
        self.put("bus_watchdog", 0xFF)
        self.put("goal_position", self.get("present_position"))
        self.position = float(self.get("present_position"))

    def reboot(self) -> None:
        """Back to the power-on state of the RAM area, except where the shaft is."""
        position = self.get("present_position")
        for name, reg in self.table.registers.items():
            if reg.address >= _EEPROM_END2 and name != "present_position":
                self.put(name, reg.default)
        self.put("present_position", position)


class ServoEmulator:
    """Emulated Dynamixel servos on a pseudo-terminal; see the module docstring.

    ``joints`` gives the servos (id, model) and the tick conversion used by :meth:`set_angle`.
    ``link`` is the stable path of the port (a symlink to the current pty); by default a fresh
    name in the temporary directory.
    """

    def __init__(
        self,
        joints: Sequence[JointSettings],
        protocol: float = 2.0,
        *,
        baudrate: int = 1_000_000,
        link: str | Path | None = None,
    ) -> None:
        if protocol not in (1.0, 2.0):
            raise ValueError(f"protocol must be 1.0 or 2.0, got {protocol}")
        self.protocol = protocol
        self.joints = {j.name: j for j in joints}
        baud = _baud_value(protocol, baudrate)
        self._servos = [_Servo(j.id, find_model(j.model, protocol), baud) for j in joints]
        self.port_path = str(
            link or Path(tempfile.gettempdir()) / f"percept-dxl-{uuid.uuid4().hex[:8]}"
        )
        self._received: Counter[str] = Counter()
        self._lock = threading.RLock()
        self._master: int | None = None
        self._slave: int | None = None
        self._outbox: list[tuple[float, int, bytes]] = []
        self._seq = itertools.count()
        self._thread: threading.Thread | None = None
        self._running = False
        self._wake_r, self._wake_w = -1, -1
        self._last_packet = time.monotonic()  # the bus watchdogs count from here
        self._playback: JointRecording | None = None
        self._played_from = 0.0  # time.monotonic() at the recording's first row

    @classmethod
    def for_profile(
        cls, joints: Sequence[JointSettings], protocol: float, **options: Any
    ) -> ServoEmulator:
        """The servos of a platform profile (its ``joints`` and ``bus.protocol``); ``options``
        as for the constructor."""
        return cls(joints, protocol, **options)

    # -- life cycle -------------------------------------------------------------------------

    def start(self) -> ServoEmulator:
        """Create the pty and answer packets in a background thread."""
        if self._running:
            return self
        self._wake_r, self._wake_w = os.pipe()
        self._plug()
        self._running = True
        self._thread = threading.Thread(
            target=self._run, name="percept-servo-emulator", daemon=True
        )
        self._thread.start()
        log.info(
            "emulating %d servo(s), Protocol %s, on %s",
            len(self._servos),
            self.protocol,
            self.port_path,
        )
        return self

    def stop(self) -> None:
        """Stop answering, close the pty and remove the port path."""
        if not self._running:
            return
        self._running = False
        os.write(self._wake_w, b"x")
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        with self._lock:
            self._unplug()
        os.close(self._wake_r)
        os.close(self._wake_w)

    def __enter__(self) -> ServoEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- positions --------------------------------------------------------------------------

    def set_ticks(self, servo_id: int, ticks: int) -> None:
        """Set a servo's present position in encoder ticks."""
        servo = self._servo(servo_id)
        lo, hi = (
            (-(2**31), 2**31 - 1) if servo.table.position_signed else (0, servo.model.max_position)
        )
        if not lo <= ticks <= hi:
            raise ValueError(f"servo {servo_id}: {ticks} ticks is outside {lo}..{hi}")
        with self._lock:
            servo.advance(time.monotonic())
            servo.place(int(ticks))

    def set_angle(self, joint: str, radians: float) -> None:
        """Set a joint's angle; 1.0 servos stop at the ends of their encoder range."""
        settings = self.joints[joint]
        self.set_ticks(settings.id, self._ticks(settings, radians))

    def _ticks(self, joint: JointSettings, radians: float) -> int:
        """The present position of ``joint`` at ``radians``, within its servo's encoder range."""
        ticks = radians_to_ticks(radians, joint)
        servo = self._servo(joint.id)
        if not servo.table.position_signed:
            ticks = min(max(ticks, 0), servo.model.max_position)
        return ticks

    def play(self, recording: JointRecording, epoch: float) -> None:
        """From now on the recorded joints' servos are where ``recording`` says, its first row at
        wall-clock time ``epoch`` (``time.time()``; the first angles hold before it, the last
        after its end). Goals are still taken but do not move them."""
        unknown = sorted(set(recording.angles) - set(self.joints))
        if unknown:
            raise ValueError(f"the recording has joints this robot lacks: {', '.join(unknown)}")
        with self._lock:
            self._playback = recording
            self._played_from = epoch - time.time() + time.monotonic()
            self._move(time.monotonic())

    @property
    def received(self) -> Counter[str]:
        """Instruction packets received so far, by instruction name (``BAD``: corrupt ones)."""
        with self._lock:
            return Counter(self._received)

    def register(self, servo_id: int, name: str) -> int:
        """The value of a control-table register, e.g. ``torque_enable``."""
        with self._lock:
            self._move(time.monotonic())
            return self._servo(servo_id).get(name)

    def angle(self, joint: str) -> float:
        """A joint's angle now, from its servo's present position."""
        settings = self.joints[joint]
        return ticks_to_radians(self.register(settings.id, "present_position"), settings)

    def goals(self, servo_id: int) -> list[int]:
        """Every goal position a servo took, oldest first (the last 100 000)."""
        with self._lock:
            return list(self._servo(servo_id).goals)

    # -- faults -----------------------------------------------------------------------------

    def mute(self, servo_id: int, muted: bool = True) -> None:
        """A mute servo neither answers nor acts on packets (unpowered, cable cut)."""
        with self._lock:
            self._servo(servo_id).faults.mute = muted

    def corrupt(self, servo_id: int, replies: int | None = None) -> None:
        """Damage the next ``replies`` replies (None: all) so their CRC (2.0) or checksum (1.0)
        fails."""
        with self._lock:
            self._servo(servo_id).faults.corrupt = math.inf if replies is None else replies

    def short_reply(self, servo_id: int, replies: int | None = None) -> None:
        """Cut the last three bytes off the next ``replies`` replies (None: all)."""
        with self._lock:
            self._servo(servo_id).faults.short = math.inf if replies is None else replies

    def glitch(self, servo_id: int, ticks: int, replies: int | None = None) -> None:
        """Make the next ``replies`` replies (None: all) that carry the present position say
        ``ticks`` there, in valid packets, while the shaft stays where it is: an encoder or
        cable glitch that no CRC catches."""
        servo = self._servo(servo_id)
        reg = servo.table["present_position"]
        signed = servo.table.position_signed
        bits = 8 * reg.size
        lo, hi = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
        if not lo <= ticks <= hi:
            raise ValueError(f"servo {servo_id}: {ticks} ticks do not fit {lo}..{hi}")
        with self._lock:
            servo.faults.glitch = math.inf if replies is None else replies
            servo.faults.glitch_ticks = ticks

    def delay(self, servo_id: int, seconds: float) -> None:
        """Answer ``seconds`` late."""
        with self._lock:
            self._servo(servo_id).faults.delay = seconds

    def set_hardware_error(self, servo_id: int, bits: int) -> None:
        """Raise hardware error bits: 2.0 Hardware Error Status (and the alert bit of every
        status packet), 1.0 the error byte of every status packet; 0 clears them."""
        top = 0x7F if self.protocol == 1.0 else 0xFF
        if not 0 <= bits <= top:
            raise ValueError(f"hardware error bits must be within 0..{top:#x}, got {bits:#x}")
        with self._lock:
            servo = self._servo(servo_id)
            if self.protocol == 1.0:
                servo.status_bits = bits
            else:
                servo.put("hardware_error_status", bits)

    def clear_faults(self, servo_id: int | None = None) -> None:
        """Undo every injected fault (of one servo, or all), hardware errors included."""
        with self._lock:
            for servo in self._servos if servo_id is None else [self._servo(servo_id)]:
                servo.faults = _Faults()
                self.set_hardware_error(servo.id, 0)

    def unplug(self) -> None:
        """The adapter vanishes: the pty closes (open ports fail) and the path disappears."""
        with self._lock:
            self._unplug()
        self._wake()
        log.info("unplugged %s", self.port_path)

    def replug(self) -> None:
        """The adapter is back at the same path (a fresh pty)."""
        with self._lock:
            if self._master is None and self._running:
                self._plug()
        self._wake()
        log.info("replugged %s", self.port_path)

    def _wake(self) -> None:
        if self._running:
            os.write(self._wake_w, b"x")

    # -- the pty ----------------------------------------------------------------------------

    def _plug(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        tmp = f"{self.port_path}.{uuid.uuid4().hex[:6]}"
        os.symlink(os.ttyname(slave), tmp)
        os.replace(tmp, self.port_path)
        # Holding the slave open keeps the pty alive while no driver has it open.
        self._master, self._slave = master, slave

    def _unplug(self) -> None:
        if self._master is None:
            return
        Path(self.port_path).unlink(missing_ok=True)
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._master = self._slave = None
        self._outbox.clear()

    def _run(self) -> None:
        buffer = b""
        while self._running:
            with self._lock:
                master = self._master
                wait = self._outbox[0][0] - time.monotonic() if self._outbox else 0.5
            fds = [self._wake_r] if master is None else [self._wake_r, master]
            try:
                ready, _, _ = select.select(fds, [], [], max(wait, 0.0))
            except (OSError, ValueError):
                ready = []  # the pty was closed by unplug() meanwhile
            # When the bytes came, as near as we know: on a loaded machine this thread may get
            # to them late, and the bus watchdog counts from their arrival.
            arrived = time.monotonic()
            if self._wake_r in ready:
                os.read(self._wake_r, 64)
            with self._lock:
                if master is not None and master in ready and master == self._master:
                    with contextlib.suppress(BlockingIOError):  # nothing to read after all
                        buffer += os.read(master, 4096)
                    while True:
                        frame, buffer = split_frame(self.protocol, buffer)
                        if frame is None:
                            break
                        self._on_frame(frame, arrived)
                elif self._master is None:
                    buffer = b""
                self._send_due()

    def _send_due(self) -> None:
        now = time.monotonic()
        while self._outbox and self._outbox[0][0] <= now:
            _, _, frame = heapq.heappop(self._outbox)
            if self._master is None:
                return
            # With nobody reading, the pty buffer fills: bytes are lost, as on a wire.
            with contextlib.suppress(BlockingIOError):
                os.write(self._master, frame)

    # -- packets ----------------------------------------------------------------------------

    def _servo(self, servo_id: int) -> _Servo:
        for servo in self._servos:
            if servo.id == servo_id:
                return servo
        raise KeyError(f"no servo with id {servo_id}")

    def _live(self, servo_id: int) -> _Servo | None:
        servo = next((s for s in self._servos if s.id == servo_id), None)
        return None if servo is None or servo.faults.mute else servo

    def _move(self, now: float) -> None:
        """Bring every servo's position up to ``now``; a watchdog that went off meanwhile
        stopped its servo where it was at that moment."""
        for servo in self._servos:
            deadline = servo.watchdog_deadline(self._last_packet)
            if deadline is not None and deadline < now:
                servo.advance(deadline)
                servo.watchdog_off()
                log.info("servo %d: bus watchdog went off", servo.id)
            servo.advance(now)
        if self._playback is not None:
            for joint, angle in self._playback.at(now - self._played_from).items():
                settings = self.joints[joint]
                self._servo(settings.id).place(self._ticks(settings, angle))

    def _on_frame(self, frame: bytes, now: float) -> None:
        self._move(now)
        self._last_packet = now
        try:
            packet = decode(self.protocol, frame, status=False)
        except PacketError as err:
            self._received["BAD"] += 1
            log.debug("ignored a corrupt packet: %s", err)
            self._on_corrupt(frame, now)
            return
        try:
            self._received[Instruction(packet.instruction).name] += 1
        except ValueError:
            self._received[f"0x{packet.instruction:02X}"] += 1
        handle = self._handle1 if self.protocol == 1.0 else self._handle2
        # Several replies to one sync/bulk read leave in the order asked, even if one is slow.
        for servo, error, params in handle(packet):
            now = self._reply(servo, error, params, now)
        if self.protocol == 2.0 and packet.instruction == Instruction.REBOOT:
            rebooted = self._live(packet.id)
            if rebooted is not None:
                rebooted.reboot()

    def _on_corrupt(self, frame: bytes, now: float) -> None:
        # A servo that receives a packet addressed to it with a bad CRC/checksum says so.
        servo = self._live(frame[2] if self.protocol == 1.0 else frame[4])
        if servo is not None:
            code = Error1.CHECKSUM if self.protocol == 1.0 else Result.CRC
            self._reply(servo, int(code), b"", now)

    def _reply(self, servo: _Servo, error: int, params: bytes, now: float) -> float:
        """Queue a status packet for ``now`` plus the servo's delay; when it will be sent."""
        if self.protocol == 1.0:
            error |= servo.status_bits
        elif servo.get("hardware_error_status"):
            error |= ALERT
        frame = encode(self.protocol, Packet(servo.id, Instruction.STATUS, params, error=error))
        f = servo.faults
        corrupt, f.corrupt = _take(f.corrupt)
        short, f.short = _take(f.short)
        if corrupt:
            # Flip the last byte the CRC/checksum covers: a position byte if there is one, so a
            # driver that took a corrupt reply would show a wrong angle.
            at = len(frame) - (2 if self.protocol == 2.0 else 1) - 1
            frame = frame[:at] + bytes([frame[at] ^ 0xFF]) + frame[at + 1 :]
        if short:
            frame = frame[:-3]
        when = now + f.delay
        heapq.heappush(self._outbox, (when, next(self._seq), frame))
        return when

    def _replies_allowed(self, servo: _Servo, instruction: int) -> bool:
        level = servo.get("status_return_level")
        if instruction == Instruction.PING:
            return True
        reads = (Instruction.READ, Instruction.SYNC_READ, Instruction.BULK_READ)
        return level >= 2 or (level == 1 and instruction in reads)

    def _handle2(self, p: Packet) -> list[tuple[_Servo, int, bytes]]:
        i = p.instruction
        if p.id == BROADCAST_ID:
            if i == Instruction.PING:
                live = sorted((s for s in self._servos if not s.faults.mute), key=lambda s: s.id)
                return [(s, 0, self._ping2(s)) for s in live]
            if i == Instruction.SYNC_READ and len(p.params) >= 4:
                address, size = _word(p.params, 0), _word(p.params, 2)
                return self._gather([(sid, address, size) for sid in p.params[4:]], Result.ACCESS)
            if i == Instruction.BULK_READ and len(p.params) % 5 == 0:
                q = p.params
                wanted = [(q[k], _word(q, k + 1), _word(q, k + 3)) for k in range(0, len(q), 5)]
                return self._gather(wanted, Result.ACCESS)
            if i == Instruction.WRITE and len(p.params) >= 3:
                for s in self._servos:
                    if not s.faults.mute:
                        self._write2(s, p.params)
            if i == Instruction.SYNC_WRITE and len(p.params) >= 4:
                self._sync_write(p.params[:2], _word(p.params, 2), p.params[4:], self._write2)
            return []
        servo = self._live(p.id)
        if servo is None:
            return []
        out: tuple[int, bytes]  # (error byte, parameters)
        if i == Instruction.PING:
            out = (Result.OK, self._ping2(servo))
        elif i == Instruction.READ:
            out = self._read(servo, p.params, 2, Result.ACCESS, Result.DATA_LENGTH)
        elif i == Instruction.WRITE:
            out = (self._write2(servo, p.params), b"")
        elif i == Instruction.REBOOT:
            out = (Result.OK, b"")  # the servo answers, then reboots (see _on_frame)
        else:
            out = (Result.INSTRUCTION, b"")
        return [(servo, int(out[0]), out[1])] if self._replies_allowed(servo, i) else []

    def _handle1(self, p: Packet) -> list[tuple[_Servo, int, bytes]]:
        i = p.instruction
        if p.id == BROADCAST_ID:
            if i == Instruction.BULK_READ and len(p.params) % 3 == 1:
                q = p.params[1:]
                wanted = [(q[k + 1], q[k + 2], q[k]) for k in range(0, len(q), 3)]
                return self._gather(wanted, Error1.RANGE)
            if i == Instruction.WRITE and len(p.params) >= 2:
                for s in self._servos:
                    if not s.faults.mute:
                        self._write1(s, p.params)
            if i == Instruction.SYNC_WRITE and len(p.params) >= 2:
                self._sync_write(p.params[:1], p.params[1], p.params[2:], self._write1)
            return []
        servo = self._live(p.id)
        if servo is None:
            return []
        if i == Instruction.PING:
            out = (0, b"")
        elif i == Instruction.READ:
            out = self._read(servo, p.params, 1, Error1.RANGE, Error1.INSTRUCTION)
        elif i == Instruction.WRITE:
            out = (self._write1(servo, p.params), b"")
        else:
            out = (Error1.INSTRUCTION, b"")
        return [(servo, int(out[0]), out[1])] if self._replies_allowed(servo, i) else []

    def _ping2(self, servo: _Servo) -> bytes:
        return servo.get("model_number").to_bytes(2, "little") + bytes(
            [servo.get("firmware_version")]
        )

    def _read(
        self, servo: _Servo, params: bytes, width: int, range_error: int, length_error: int
    ) -> tuple[int, bytes]:
        """READ with ``width``-byte address and length fields."""
        if len(params) != 2 * width:
            return length_error, b""
        address = int.from_bytes(params[:width], "little")
        size = int.from_bytes(params[width:], "little")
        data = servo.read(address, size)
        return (range_error, b"") if data is None else (0, data)

    def _gather(
        self, wanted: list[tuple[int, int, int]], range_error: int
    ) -> list[tuple[_Servo, int, bytes]]:
        """Replies to a sync or bulk read, in the order asked, skipping servos that are absent."""
        out = []
        for servo_id, address, size in wanted:
            servo = self._live(servo_id)
            if servo is None:
                continue
            data = servo.read(address, size)
            out.append((servo, 0, data) if data is not None else (servo, int(range_error), b""))
        return out

    def _sync_write(
        self, address: bytes, size: int, rest: bytes, write: Callable[[_Servo, bytes], int]
    ) -> None:
        """SYNC WRITE: ``size`` bytes at ``address`` for each servo listed in ``rest`` (id,
        data...); no servo answers, so a refused write is only logged."""
        if size < 1 or len(rest) % (size + 1):
            return
        for k in range(0, len(rest), size + 1):
            servo = self._live(rest[k])
            if servo is not None:
                error = write(servo, address + rest[k + 1 : k + 1 + size])
                if error:
                    log.debug("servo %d refused a sync write (error %d)", servo.id, error)

    def _write2(self, servo: _Servo, params: bytes) -> int:
        if len(params) < 3:
            return Result.DATA_LENGTH
        address, data = _word(params, 0), params[2:]
        if not servo.writable(address, len(data)):
            return Result.ACCESS
        if address < _EEPROM_END2 and servo.get("torque_enable"):
            return Result.ACCESS
        watchdog = servo.table["bus_watchdog"].address
        if servo.get("bus_watchdog") == 0xFF and (
            servo.touches("goal_position", address, len(data))
            or (servo.touches("bus_watchdog", address, len(data)) and data[watchdog - address])
        ):
            return Result.DATA_RANGE  # after the watchdog went off, until it is written 0
        servo.write(address, data)
        return Result.OK

    def _write1(self, servo: _Servo, params: bytes) -> int:
        if len(params) < 2:
            return Error1.INSTRUCTION
        address, data = params[0], params[1:]
        if not servo.writable(address, len(data)):
            return Error1.RANGE
        servo.write(address, data)
        return 0


def _word(data: bytes, at: int) -> int:
    return data[at] | data[at + 1] << 8
