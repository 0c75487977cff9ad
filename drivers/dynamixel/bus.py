"""Joint angles from Dynamixel servos: a reader thread that owns the serial port.

Protocol 2.0 buses are read with one sync read of present position for all joints per cycle;
Protocol 1.0 buses one servo at a time. A servo that stops answering (after the retries) leaves
the cycle and is probed every ``probe_interval`` so the others keep their rate; its joint turns
stale ``stale_after`` seconds after its last answer (the status says why it stopped answering).
Hardware errors are polled (2.0: the Hardware Error Status register, every
``error_poll_interval`` and at once when a status packet newly has its alert bit set) or taken
from every status packet (1.0). A lost port is reopened with exponential backoff. Nothing here
raises into the caller's thread and nothing is ever written to a servo (the runtime never
switches torque on).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

from percept.drivers.dynamixel.errors import PortLost, PortUnavailable, ReadFailed
from percept.drivers.dynamixel.link import Link
from percept.drivers.dynamixel.models import Model, error_words, find_model
from percept.drivers.dynamixel.protocol import ALERT
from percept.drivers.dynamixel.settings import BusSettings, JointSettings
from percept.drivers.joints import JointHistory, JointSample

log = logging.getLogger("percept.dynamixel")

T = TypeVar("T")

# Single reads of present position cycle through this many lengths (see _read_joint); the
# registers after present position exist on every model (velocity/trajectory, speed/load).
_LENGTHS = 4


def ticks_to_radians(ticks: int, joint: JointSettings) -> float:
    """Joint angle of an encoder reading: ``sign * (ticks - zero_tick) * 2*pi / ticks_per_rev``."""
    return joint.sign * (ticks - joint.zero_tick) * 2.0 * math.pi / joint.ticks_per_rev


def radians_to_ticks(angle: float, joint: JointSettings) -> int:
    """The encoder reading nearest to joint angle ``angle`` (inverse of ticks_to_radians)."""
    return round(joint.zero_tick + joint.sign * angle * joint.ticks_per_rev / (2.0 * math.pi))


@dataclass
class _Joint:
    """What the reader knows about one servo."""

    settings: JointSettings
    model: Model
    last_ok: float = 0.0
    absent: bool = False  # left the read cycle after failing; probed now and then
    stale: bool = False
    errors: list[str] = field(default_factory=list)
    reads: int = 0  # single reads so far; picks the length of the next one
    problem: str | None = None  # why it stopped answering (absent)

    @property
    def name(self) -> str:
        return self.settings.name


class DynamixelBus:
    """A :class:`percept.drivers.joints.JointSource` reading Dynamixel servos through dynamixel-sdk.

    ``status()["state"]`` is "stopped", "connecting", "connected", "reconnecting" (the port
    vanished or cannot be opened yet) or "failed" (the port cannot be opened for a reason a person
    must fix, such as permissions; it is still retried at the longest backoff).
    """

    def __init__(
        self,
        bus: BusSettings,
        joints: Sequence[JointSettings],
        *,
        history: int = 512,
        logger: str = log.name,
    ) -> None:
        if not joints:
            raise ValueError("no joints to read")
        # A bus on the servo emulator logs under its own name: its late or cut replies come
        # from a starved emulator thread, not from hardware.
        self._log = logging.getLogger(logger)
        self.settings = bus
        self._joints = [_Joint(j, find_model(j.model, bus.protocol)) for j in joints]
        self._history = JointHistory(history)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._state = "stopped"
        self._problem: str | None = None
        self._retries = 0
        self._failed_reads = 0
        self._reconnects = 0
        self._cycles: deque[float] = deque()
        self._error_poll_due = 0.0
        self._sync_reads = 0

    # -- JointSource ------------------------------------------------------------------------

    def start(self) -> None:
        """Start the reader thread (no-op if running); the port is opened there."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._set_state("connecting", None)
        self._thread = threading.Thread(target=self._run, name="percept-dynamixel", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop reading and close the port."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self._set_state("stopped", self._problem)

    def angles_at(self, t: float) -> JointSample | None:
        """Joint angles at monotonic time ``t`` (interpolated); None before the first reading."""
        sample = self._history.at(t)
        return sample if sample.angles else None

    def latest(self) -> JointSample | None:
        """The newest reading of every joint; None before the first one."""
        return self._history.latest()

    def status(self) -> dict[str, Any]:
        """State, stale joints, hardware errors and counters, JSON-able."""
        now = time.monotonic()
        with self._lock:
            while self._cycles and self._cycles[0] < now - 1.0:
                self._cycles.popleft()
            return {
                "state": self._state,
                "port": self.settings.port,
                "protocol": self.settings.protocol,
                "stale": sorted(j.name for j in self._joints if j.stale),
                "errors": {j.name: list(j.errors) for j in self._joints if j.errors},
                "not_answering": {j.name: j.problem for j in self._joints if j.problem},
                "reads_per_s": float(len(self._cycles)),  # read cycles in the last second
                "retries": self._retries,
                "failed_reads": self._failed_reads,
                "reconnects": self._reconnects,
                "problem": self._problem,
            }

    def __enter__(self) -> DynamixelBus:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- the reader thread ------------------------------------------------------------------

    def _set_state(self, state: str, problem: str | None) -> None:
        with self._lock:
            changed = (state, problem) != (self._state, self._problem)
            self._state, self._problem = state, problem
        if changed and state in ("reconnecting", "failed"):
            self._log.warning("servo bus %s: %s (%s)", self.settings.port, state, problem)
        elif changed and state == "connected":
            self._log.info("servo bus %s: connected", self.settings.port)

    def _run(self) -> None:
        first, largest = self.settings.reconnect_backoff
        delay, connected_before = first, False
        while not self._stop.is_set():
            try:
                link = Link(
                    self.settings.port,
                    self.settings.baudrate,
                    self.settings.protocol,
                    self.settings.timeout,
                )
            except PortUnavailable as err:
                self._mark_stale(self._joints)
                if err.fixable_by_waiting:
                    self._set_state("reconnecting" if connected_before else "connecting", str(err))
                else:
                    self._set_state("failed", str(err))
                    delay = largest
                self._stop.wait(delay)
                delay = min(max(delay * 2.0, first), largest)
                continue
            if connected_before:
                with self._lock:
                    self._reconnects += 1
            connected_before, delay = True, first
            self._set_state("connected", None)
            try:
                self._poll(link)
            except PortLost as err:
                self._lost(f"port lost: {err}")
            except Exception as err:  # a bug or an SDK surprise must not end the thread
                log.exception("servo bus %s: unexpected error", self.settings.port)
                self._lost(f"unexpected error: {err!r}")
            finally:
                link.close()
            self._stop.wait(first)

    def _lost(self, problem: str) -> None:
        self._set_state("reconnecting", problem)
        self._mark_stale(self._joints)

    def _poll(self, link: Link) -> None:
        s = self.settings
        period = 1.0 / s.rate
        now = time.monotonic()
        for joint in self._joints:
            joint.last_ok, joint.absent = now, False
        next_cycle, next_probe = now, now + s.probe_interval
        self._error_poll_due = now
        while not self._stop.is_set():
            if self._read_positions(link):
                with self._lock:
                    self._cycles.append(time.monotonic())
            now = time.monotonic()
            if now >= next_probe:
                for joint in [j for j in self._joints if j.absent]:
                    self._read_joint(link, joint, retries=0)
                next_probe = now + s.probe_interval
            if s.protocol == 2.0 and now >= self._error_poll_due:
                self._poll_errors(link)
                self._error_poll_due = now + s.error_poll_interval
            self._mark_stale([j for j in self._joints if now - j.last_ok > s.stale_after])
            next_cycle = max(next_cycle + period, now)
            self._stop.wait(next_cycle - now)

    def _read_positions(self, link: Link) -> bool:
        """Read every servo still answering; whether any angle was read."""
        present = [j for j in self._joints if not j.absent]
        if self.settings.protocol == 2.0 and present:
            reg = present[0].model.table["present_position"]
            ids = [j.settings.id for j in present]

            def sync_read() -> dict[int, tuple[bytes, int]]:
                self._sync_reads += 1  # lengths in turn, as in _read_joint
                size = reg.size + self._sync_reads % _LENGTHS
                return link.sync_read(ids, reg.address, size)

            try:
                t, data = self._attempt(sync_read, self.settings.retries)
            except ReadFailed:
                pass  # find out servo by servo who is silent
            else:
                self._record(t, [(j, data[j.settings.id][0][: reg.size]) for j in present])
                if any(data[j.settings.id][1] & ALERT and not j.errors for j in present):
                    self._error_poll_due = 0.0  # a servo flags a new hardware error: look now
                return True
        read = [self._read_joint(link, joint, retries=self.settings.retries) for joint in present]
        return any(read)

    def _read_joint(self, link: Link, joint: _Joint, retries: int) -> bool:
        """Read one servo's position (and 1.0 error byte); whether it answered."""
        reg = joint.model.table["present_position"]

        def read() -> tuple[bytes, int]:
            # Dynamixel replies carry no sequence number: a reply that comes after its read
            # timed out would pass as the answer to the next read of that servo. Asking for
            # 0-3 bytes more than the position, in turn, lets Link's length check refuse it.
            joint.reads += 1
            size = reg.size + joint.reads % _LENGTHS
            return link.read(joint.settings.id, reg.address, size)

        try:
            t, (data, error) = self._attempt(read, retries)
        except ReadFailed as err:
            if not joint.absent:
                self._log.warning(
                    "%s (id %d) does not answer: %s", joint.name, joint.settings.id, err
                )
                with self._lock:
                    joint.absent, joint.problem = True, err.reason
            return False
        self._record(t, [(joint, data[: reg.size])])
        if self.settings.protocol == 1.0:
            self._set_errors(joint, error_words(error, 1.0))
        elif error & ALERT and not joint.errors:
            self._error_poll_due = 0.0  # the servo flags a new hardware error: look now
        return True

    def _attempt(self, read: Callable[[], T], retries: int) -> tuple[float, T]:
        """(mid-transaction time, result) of the first of ``1 + retries`` attempts to succeed."""
        for attempt in range(retries + 1):
            t0 = time.monotonic()
            try:
                result = read()
            except ReadFailed as err:
                with self._lock:
                    if attempt < retries:
                        self._retries += 1
                    else:
                        self._failed_reads += 1
                self._log.debug("read failed (attempt %d): %s", attempt + 1, err)
                if attempt == retries:
                    raise
                continue
            return (t0 + time.monotonic()) / 2.0, result
        raise AssertionError("unreachable")

    def _record(self, t: float, readings: Sequence[tuple[_Joint, bytes]]) -> None:
        angles = {}
        for joint, data in readings:
            ticks = int.from_bytes(data, "little", signed=joint.model.table.position_signed)
            angles[joint.name] = ticks_to_radians(ticks, joint.settings)
            if joint.absent or joint.stale:
                self._log.info("%s (id %d) answers again", joint.name, joint.settings.id)
            with self._lock:
                joint.last_ok, joint.absent, joint.stale, joint.problem = t, False, False, None
        self._history.add(t, angles)

    def _poll_errors(self, link: Link) -> None:
        for joint in self._joints:
            if joint.absent:
                continue
            reg = joint.model.table["hardware_error_status"]
            try:
                data, _ = link.read(joint.settings.id, reg.address, reg.size)
            except ReadFailed:
                with self._lock:
                    self._failed_reads += 1
                continue  # silence is handled by the position reads
            self._set_errors(joint, error_words(data[0], 2.0))

    def _set_errors(self, joint: _Joint, errors: list[str]) -> None:
        if errors != joint.errors:
            if errors:
                self._log.warning("%s (id %d) reports: %s", joint.name, joint.settings.id, errors)
            else:
                self._log.info("%s (id %d) reports no more errors", joint.name, joint.settings.id)
        with self._lock:
            joint.errors = errors

    def _mark_stale(self, joints: Sequence[_Joint]) -> None:
        fresh = [j for j in joints if not j.stale]
        if not fresh:
            return
        with self._lock:
            for joint in fresh:
                joint.stale = True
        self._history.mark_stale(j.name for j in fresh)
        self._log.warning("stale: %s", ", ".join(j.name for j in fresh))
