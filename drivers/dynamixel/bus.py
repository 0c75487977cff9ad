"""Joint angles from Dynamixel servos: a reader thread that owns the serial port.

Protocol 2.0 buses are read with one sync read of present position for all joints per cycle;
Protocol 1.0 buses one servo at a time. A servo that stops answering (after the retries) leaves
the cycle and is probed every ``probe_interval`` so the others keep their rate; its joint turns
stale ``stale_after`` seconds after its last answer (the status says why it stopped answering).
Hardware errors are polled (2.0: the Hardware Error Status register, every
``error_poll_interval`` and at once when a status packet newly has its alert bit set) or taken
from every status packet (1.0). A lost port is reopened with exponential backoff. Nothing here
raises into the caller's thread.

Servos are written to only on a bus made with ``gaze`` settings, only for the gaze joints and
only after :meth:`DynamixelBus.engage`: on the same thread, between the reads, torque goes on
holding each head servo where it is (2.0: the bus watchdog armed first), then one SYNC WRITE of
speed and goal position per cycle carries the goals asked for with :meth:`DynamixelBus.move`.
Every goal sent, holds included, is clipped to the joint limits in one place
(:meth:`DynamixelBus._sync_goals`), whatever asked for it.

A position reading that cannot be true (beyond a revolution from the joint's zero, or further
from the last reading than the servo's top speed allows) is dropped: it goes neither into the
history nor into a goal. A gaze joint that reads outside its limits (a horn mounted a tooth
off, a head pushed by hand) is a fault of that servo, as is a hardware error, a stale joint, a
refused write or a watchdog that went off: the writes stop, and the head is held at the last
good reading or released, as ``torque_at_stop`` says; a head outside its limits is never
engaged. :meth:`DynamixelBus.disengage` and stopping the bus hold or release it the same way.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

from percept.drivers.dynamixel.errors import PortLost, PortUnavailable, ReadFailed, WriteFailed
from percept.drivers.dynamixel.link import Link
from percept.drivers.dynamixel.models import Model, error_words, find_model
from percept.drivers.dynamixel.protocol import ALERT
from percept.drivers.dynamixel.settings import (
    WATCHDOG_UNIT,
    BusSettings,
    GazeSettings,
    JointSettings,
)
from percept.drivers.joints import JointHistory, JointSample

log = logging.getLogger("percept.dynamixel")

T = TypeVar("T")

# Single reads of present position cycle through this many lengths (see _read_joint); the
# registers after present position exist on every model (velocity/trajectory, speed/load).
_LENGTHS = 4

LIMIT_SLACK = math.radians(1.0)
"""A gaze joint reading this far past a limit is still inside it: a servo holding a goal at its
limit under load sits a few ticks beyond it (1 degree is 11 ticks of a 4096-tick encoder)."""

JUMP_SLACK = 0.1
"""Seconds added to the time between two readings when judging whether a servo could have
turned that far: replies are timed on this side of the bus, late by up to a loaded machine's
scheduling delay."""


def ticks_to_radians(ticks: int, joint: JointSettings) -> float:
    """Joint angle of an encoder reading: ``sign * (ticks - zero_tick) * 2*pi / ticks_per_rev``."""
    return joint.sign * (ticks - joint.zero_tick) * 2.0 * math.pi / joint.ticks_per_rev


def radians_to_ticks(angle: float, joint: JointSettings) -> int:
    """The encoder reading nearest to joint angle ``angle`` (inverse of ticks_to_radians)."""
    return round(joint.zero_tick + joint.sign * angle * joint.ticks_per_rev / (2.0 * math.pi))


def goal_ticks(angle: float, joint: JointSettings, model: Model) -> int:
    """The goal position for joint angle ``angle``: the nearest tick whose angle lies within the
    joint's ``min``/``max`` and inside the encoder range, whatever ``angle`` is."""
    if not math.isfinite(angle):
        raise ValueError(f"{joint.name}: goal angle {angle} is not a number")
    ticks = radians_to_ticks(min(max(angle, joint.min), joint.max), joint)
    if ticks_to_radians(ticks, joint) > joint.max:  # rounding went past a limit by < a tick
        ticks -= joint.sign
    elif ticks_to_radians(ticks, joint) < joint.min:
        ticks += joint.sign
    ticks = min(max(ticks, 0), model.max_position)
    if not joint.min <= ticks_to_radians(ticks, joint) <= joint.max:
        raise ValueError(
            f"{joint.name}: no encoder tick lies within min {joint.min} and max {joint.max}"
        )
    return ticks


def clip_ticks(ticks: int, joint: JointSettings, model: Model) -> int:
    """``ticks`` if its angle lies within the joint's limits, else the nearest tick that does."""
    return goal_ticks(ticks_to_radians(ticks, joint), joint, model)


def impossible(
    ticks: int, joint: JointSettings, model: Model, t: float, before: Sequence[tuple[float, int]]
) -> str | None:
    """Why a position reading at monotonic time ``t`` cannot be true, or None: more than a
    revolution from the joint's zero, or further from every reading ``before`` (time, ticks)
    than the servo turns at its top speed meanwhile."""
    if abs(ticks - joint.zero_tick) > joint.ticks_per_rev:
        return f"reads tick {ticks}: beyond a revolution from its zero ({joint.zero_tick})"
    top = model.max_speed * model.ticks_per_rev / (2.0 * math.pi)  # encoder ticks per second
    gaps = [(abs(ticks - then_ticks), t - then) for then, then_ticks in before]
    if gaps and all(gap > top * (max(dt, 0.0) + JUMP_SLACK) for gap, dt in gaps):
        gap, dt = min(gaps)
        return f"jumped {gap} ticks in {dt * 1000:.0f} ms: faster than it can turn"
    return None


def outside_limits(ticks: int, joint: JointSettings) -> str | None:
    """Why a gaze joint must not be moved from reading ``ticks``, or None: outside its limits
    (by more than :data:`LIMIT_SLACK`)."""
    angle = ticks_to_radians(ticks, joint)
    if joint.min - LIMIT_SLACK <= angle <= joint.max + LIMIT_SLACK:
        return None
    return f"reads {angle:+.3f} rad, outside its limits {joint.min:+.3f}..{joint.max:+.3f}"


def speed_units(speed: float, joint: JointSettings, model: Model) -> int:
    """The speed register value for joint speed ``speed`` rad/s: at least 1 (0 would mean "as
    fast as it goes") and at most the model's top speed."""
    shaft = speed * joint.ticks_per_rev / model.ticks_per_rev
    unit = model.table.speed_unit
    return max(1, min(round(shaft / unit), math.floor(model.max_speed / unit)))


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
    moves: bool = False  # a gaze joint
    taken: tuple[float, int] | None = None  # (time, ticks) of the last reading that could be true
    seen: tuple[float, int] | None = None  # (time, ticks) of the last one within a revolution
    good: int | None = None  # the last reading inside the limits: the only goal a hold sends
    wrong: str | None = None  # why the last reading cannot be used, or None
    warned: float = -math.inf  # when a reading that cannot be used was last logged
    told: bool = False  # and the good readings since not yet

    @property
    def name(self) -> str:
        return self.settings.name


class DynamixelBus:
    """A :class:`percept.drivers.joints.JointSource` reading Dynamixel servos through dynamixel-sdk,
    and moving the ``gaze`` joints when asked (see the module docstring).

    ``status()["state"]`` is "stopped", "connecting", "connected", "reconnecting" (the port
    vanished or cannot be opened yet) or "failed" (the port cannot be opened for a reason a person
    must fix, such as permissions; it is still retried at the longest backoff).
    ``status()["gaze"]`` (with ``gaze`` settings) says whether the head is "off" (not written
    to), "on" (torque on, goals sent) or "stopped" (by a fault: ``problem``), and the goals.
    """

    def __init__(
        self,
        bus: BusSettings,
        joints: Sequence[JointSettings],
        *,
        history: int = 512,
        logger: str = log.name,
        gaze: GazeSettings | None = None,
        emulated: bool = False,
    ) -> None:
        if not joints:
            raise ValueError("no joints to read")
        # A bus on the servo emulator logs under its own name, and says a silent servo is the
        # emulator's: its late or cut replies come from a starved emulator thread, not from
        # hardware.
        self._log = logging.getLogger(logger)
        self._emulated = emulated
        self.settings = bus
        self._joints = [_Joint(j, find_model(j.model, bus.protocol)) for j in joints]
        self.gaze = gaze
        self._movers: list[_Joint] = []
        if gaze is not None:
            by_name = {j.name: j for j in self._joints}
            unknown = [n for n in gaze.joints if n not in by_name]
            if unknown:
                raise ValueError(
                    f"gaze joint(s) {', '.join(unknown)} have no servo; the servos: "
                    f"{', '.join(by_name)}"
                )
            self._movers = [by_name[n] for n in gaze.joints]
            for mover in self._movers:  # limits that no tick can meet fail here, not later
                goal_ticks(mover.settings.min, mover.settings, mover.model)
                mover.moves = True
            if bus.protocol == 2.0 and gaze.watchdog < 3.0 / bus.rate:
                # Shorter, and one slow cycle (a retried read) would set it off.
                raise ValueError(
                    f"gaze watchdog ({gaze.watchdog} s) must be at least three read periods "
                    f"({3.0 / bus.rate:g} s at rate {bus.rate:g})"
                )
        self._want_on = False
        self._goals: dict[str, int] = {}  # goal ticks asked for
        self._speeds: dict[str, int] = {}  # speed register values asked for
        self._gaze_state = "off"
        self._gaze_problem: str | None = None
        self._bad_readings = 0
        self._sync_writes = 0
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
                # Readings not used (see the module docstring): the count, and why now.
                "bad_readings": self._bad_readings,
                "reading_faults": {j.name: j.wrong for j in self._joints if j.wrong},
                "not_answering": {j.name: j.problem for j in self._joints if j.problem},
                "reads_per_s": float(len(self._cycles)),  # read cycles in the last second
                "retries": self._retries,
                "failed_reads": self._failed_reads,
                "reconnects": self._reconnects,
                "problem": self._problem,
                **({"gaze": self._gaze_status()} if self.gaze is not None else {}),
            }

    # -- writes ---------------------------------------------------------------------------------

    def engage(self) -> None:
        """Ask for torque on the gaze joints, held where they are, watchdog armed; after a stop
        by a fault, try again (it stops again at once if the fault is still there; while the
        port is gone it stays stopped)."""
        self._need_gaze()
        with self._lock:
            self._want_on, self._goals, self._speeds = True, {}, {}
            if self._gaze_state == "stopped" and self._state == "connected":
                self._gaze_state = "off"

    def disengage(self) -> None:
        """Stop moving: the head holds where it is or goes limp (``torque_at_stop``)."""
        self._need_gaze()
        with self._lock:
            self._want_on = False

    def move(self, goals: Mapping[str, float], speed: float | None = None) -> dict[str, float]:
        """Ask for goal angles (radians) of gaze joints, approached at ``speed`` rad/s (default
        and at most the gaze ``max_speed``); sent with every cycle while engaged. The goals as
        they will be sent: clipped to each joint's limits and rounded to a tick."""
        gaze = self._need_gaze()
        movers = {j.name: j for j in self._movers}
        unknown = [n for n in goals if n not in movers]
        if unknown:
            raise ValueError(f"not a gaze joint: {', '.join(unknown)} (gaze: {', '.join(movers)})")
        pace = gaze.max_speed if speed is None else min(speed, gaze.max_speed)
        if not pace > 0:
            raise ValueError(f"speed must be positive, got {speed}")
        ticks = {n: goal_ticks(a, movers[n].settings, movers[n].model) for n, a in goals.items()}
        units = {n: speed_units(pace, movers[n].settings, movers[n].model) for n in goals}
        with self._lock:
            self._goals.update(ticks)
            self._speeds.update(units)
        return {n: ticks_to_radians(t, movers[n].settings) for n, t in ticks.items()}

    def _need_gaze(self) -> GazeSettings:
        if self.gaze is None:
            raise ValueError("this bus was opened for reading only (no gaze settings)")
        return self.gaze

    def _gaze_status(self) -> dict[str, Any]:
        movers = {j.name: j.settings for j in self._movers}
        return {
            "state": self._gaze_state,
            "problem": self._gaze_problem,
            "goals": {n: ticks_to_radians(t, movers[n]) for n, t in self._goals.items()},
            "sync_writes": self._sync_writes,
        }

    def _set_gaze(self, state: str, problem: str | None) -> None:
        with self._lock:
            changed = state != self._gaze_state
            self._gaze_state, self._gaze_problem = state, problem
            if state != "on":
                self._goals, self._speeds = {}, {}  # a stopped head is sent no goals
        if changed and problem:
            self._log.warning("gaze %s: %s", state, problem)
        elif changed:
            self._log.info("gaze %s", state)

    def _write(self, link: Link) -> None:
        """This cycle's writes (nothing without gaze joints or before :meth:`engage`)."""
        if not self._movers:
            return
        with self._lock:
            want, state = self._want_on, self._gaze_state
            goals, speeds = dict(self._goals), dict(self._speeds)
        if not want:
            if state != "off":
                self._disengage(link)
            return
        if state == "stopped":
            return  # until engage() is asked again
        fault = self._mover_fault()
        if fault is not None:
            if state == "on":
                self._halt(link)
            self._set_gaze("stopped", fault)
            return
        try:
            if state == "off":
                if any(j.good is None for j in self._movers):
                    return  # not read yet: nothing to hold
                self._engage(link)
                if self._gaze_state != "on":
                    return
            if goals:
                self._sync_goals(link, {n: (goals[n], speeds[n]) for n in goals})
        except WriteFailed as err:
            self._halt(link)
            self._set_gaze("stopped", f"write failed: {err}")

    def _mover_fault(self) -> str | None:
        """Why the gaze joints must not be moved now, or None."""
        for joint in self._movers:
            if joint.stale or joint.absent:
                return f"{joint.name} stale" + (f" ({joint.problem})" if joint.problem else "")
            if joint.errors:
                return f"{joint.name} reports {', '.join(joint.errors)}"
            if joint.wrong:
                return f"{joint.name} {joint.wrong}"
        return None

    def _engage(self, link: Link) -> None:
        """Torque on, held where the head is; stopped instead (nothing turned on) if the
        reading taken for the hold shows a fault."""
        assert self.gaze is not None
        self._hold(link, strict=True)
        fault = self._mover_fault()
        if fault is not None:
            self._set_gaze("stopped", fault)
            return
        for joint in self._movers:
            if self.settings.protocol == 2.0:
                units = round(self.gaze.watchdog / WATCHDOG_UNIT)
                # 0 first: clears a watchdog that went off before (its value is then 0xFF).
                self._put(link, joint, "bus_watchdog", 0)
                self._put(link, joint, "bus_watchdog", units)
            self._put(link, joint, "torque_enable", 1)
        self._set_gaze("on", None)

    def _put(self, link: Link, joint: _Joint, name: str, value: int) -> None:
        """Write one register, acknowledged, with the bus's retries for lost replies (writing
        the same value again is harmless); a refusal is not retried."""
        reg = joint.model.table[name]
        data = value.to_bytes(reg.size, "little")
        for attempt in range(self.settings.retries + 1):
            try:
                link.write(joint.settings.id, reg.address, data)
                return
            except WriteFailed as err:
                if err.reason.startswith("refused") or attempt == self.settings.retries:
                    raise
                with self._lock:
                    self._retries += 1

    def _hold(self, link: Link, strict: bool = False) -> None:
        """Goal = the last good position read (inside the limits), for the gaze joints still
        answering: the head stops. Best effort unless ``strict``."""
        assert self.gaze is not None
        self._read_positions(link)  # where it is now, not a cycle ago: it may be moving
        now = {
            j.name: (j.good, speed_units(self.gaze.max_speed, j.settings, j.model))
            for j in self._movers
            if j.good is not None and not j.absent
        }
        try:
            self._sync_goals(link, now)
        except WriteFailed as err:
            if strict:
                raise
            self._log.warning("could not hold the head: %s", err)

    def _halt(self, link: Link) -> None:
        """The torque policy: hold where it is (the last good reading) or release."""
        assert self.gaze is not None
        self._hold(link)
        if self.gaze.torque_at_stop == "release":
            for joint in self._movers:
                try:
                    self._put(link, joint, "torque_enable", 0)
                except WriteFailed as err:
                    self._log.warning("%s: could not release: %s", joint.name, err)

    def _disengage(self, link: Link) -> None:
        """The torque policy; the watchdog disarmed."""
        self._halt(link)
        if self.settings.protocol == 2.0:
            for joint in self._movers:
                try:
                    self._put(link, joint, "bus_watchdog", 0)
                except WriteFailed as err:
                    self._log.warning("%s: could not disarm the watchdog: %s", joint.name, err)
        self._set_gaze("off", None)

    def _sync_goals(self, link: Link, goals: Mapping[str, tuple[int | None, int]]) -> None:
        """One SYNC WRITE of speed and goal position (adjacent registers) to gaze joints, each
        goal clipped to its joint's limits: the one place every goal passes."""
        data: dict[int, bytes] = {}
        address = size = 0
        for joint in self._movers:
            if joint.name not in goals:
                continue
            asked, units = goals[joint.name]
            assert asked is not None
            ticks = clip_ticks(asked, joint.settings, joint.model)
            table = joint.model.table
            goal, speed = table["goal_position"], table[table.speed_register]
            goal_bytes = ticks.to_bytes(goal.size, "little", signed=ticks < 0)
            speed_bytes = units.to_bytes(speed.size, "little")
            first, second = (speed_bytes, goal_bytes)
            if goal.address < speed.address:
                first, second = goal_bytes, speed_bytes
            data[joint.settings.id] = first + second
            address, size = min(goal.address, speed.address), goal.size + speed.size
        if data:
            link.sync_write(address, size, data)
            with self._lock:
                self._sync_writes += 1

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
        with self._lock:
            moving = self._want_on or self._gaze_state != "off"
        if moving:  # the fault stays while the port is gone (see engage)
            self._set_gaze("stopped", problem)

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
            self._write(link)
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
        if self._gaze_state != "off":
            self._disengage(link)  # stopping: the torque policy

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
                problem = err.reason
                if self._emulated:
                    problem = f"the servo emulator replied late, a busy machine: {err.reason}"
                    self._log.warning("%s (id %d): %s", joint.name, joint.settings.id, problem)
                else:
                    self._log.warning(
                        "%s (id %d) does not answer: %s", joint.name, joint.settings.id, err
                    )
                with self._lock:
                    joint.absent, joint.problem = True, problem
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
            before = [r for r in (joint.taken, joint.seen) if r is not None]
            wrong = impossible(ticks, joint.settings, joint.model, t, before)
            if abs(ticks - joint.settings.zero_tick) <= joint.settings.ticks_per_rev:
                joint.seen = (t, ticks)  # a jump seen twice running is a real one
            if wrong is not None:
                # Dropped: not an answer either, so a servo that only says this turns stale.
                with self._lock:
                    self._bad_readings += 1
                self._set_wrong(joint, wrong, t, "dropped")
                continue
            angles[joint.name] = ticks_to_radians(ticks, joint.settings)
            if joint.absent or joint.stale:
                self._log.info("%s (id %d) answers again", joint.name, joint.settings.id)
            outside = outside_limits(ticks, joint.settings) if joint.moves else None
            with self._lock:
                joint.last_ok, joint.absent, joint.stale, joint.problem = t, False, False, None
                joint.taken = (t, ticks)
                if outside is None:
                    joint.good = ticks
                else:
                    self._bad_readings += 1
            self._set_wrong(joint, outside, t, "never a goal")
        if angles:
            self._history.add(t, angles)

    def _set_wrong(self, joint: _Joint, wrong: str | None, t: float, what: str) -> None:
        """Keep why the joint's last reading cannot be used. Logged when that begins, at most
        once a second: a glitching servo may be wrong every other cycle."""
        if wrong is not None and not joint.told and t - joint.warned >= 1.0:
            self._log.warning("%s (id %d) %s: %s", joint.name, joint.settings.id, wrong, what)
            joint.warned, joint.told = t, True
        elif wrong is None and joint.told:
            self._log.info("%s (id %d) reads good positions again", joint.name, joint.settings.id)
            joint.told = False
        with self._lock:
            joint.wrong = wrong

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
        if self._gaze_state == "on":
            self._poll_watchdog(link)

    def _poll_watchdog(self, link: Link) -> None:
        """A watchdog that went off (the bus was silent too long) refuses goals from then on,
        and a sync write is never answered: look for it."""
        for joint in self._movers:
            reg = joint.model.table["bus_watchdog"]
            try:
                data, _ = link.read(joint.settings.id, reg.address, reg.size)
            except ReadFailed:
                continue
            if data[0] == 0xFF:
                self._halt(link)
                self._set_gaze("stopped", f"{joint.name}: the bus watchdog went off")
                return

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
        names = ", ".join(j.name for j in fresh)
        if self._emulated:
            self._log.warning("stale: %s (the servo emulator replies late, a busy machine)", names)
        else:
            self._log.warning("stale: %s", names)
