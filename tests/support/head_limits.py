"""A head on the servo emulator through glitched, muted and unplugged cycles, and every goal its
servos took (``tests/drivers/dynamixel/test_dynamixel_writes.py`` runs a few hundred cycles,
``bench/limits.py`` ten thousand).

The real driver (:class:`~percept.drivers.dynamixel.bus.DynamixelBus` over dynamixel-sdk) moves
the head of a shipped profile (``robotis-op3`` on Protocol 2.0, ``myon`` on 1.0) on the emulator.
A cycle is one read period of the bus; in each, a seeded schedule may ask for new goals anywhere
(far past the limits included), start a fault, or ask to engage again as gaze does after a stop.
The faults: replies that say impossible positions in valid packets (outside the limits, beyond a
revolution, a jump to the other end, any value the register holds), corrupt replies, a mute
servo, the port unplugged, the shaft pushed past a limit by hand, hardware error bits, a
disengage, and the bus stopped and started again. Afterwards every goal position each servo took
(the emulator logs them all) is checked against the joint's limits.
"""

from __future__ import annotations

import random
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from percept.drivers.dynamixel.bus import DynamixelBus, radians_to_ticks, ticks_to_radians
from percept.drivers.dynamixel.emulator import ServoEmulator
from percept.drivers.dynamixel.models import find_model
from percept.drivers.dynamixel.settings import GazeSettings, JointSettings
from percept.runtime.settings.profile import load_profile

PROFILES = {2.0: "robotis-op3", 1.0: "myon"}
FAULTS = ("glitch", "corrupt", "mute", "unplug", "push", "error", "disengage", "restart")


@dataclass
class Outcome:
    """What the cycles did and what the servos took."""

    protocol: float
    cycles: int = 0
    seconds: float = 0.0
    goals: dict[str, int] = field(default_factory=dict)  # goal positions taken, per joint
    outside: dict[str, list[float]] = field(default_factory=dict)  # of which outside, radians
    injected: Counter[str] = field(default_factory=Counter)
    stops: int = 0  # times gaze stopped on a fault
    bad_readings: int = 0  # readings the driver did not use (all runs of the bus)


def _register_range(joint: JointSettings, protocol: float) -> tuple[int, int]:
    """The values the present position register can carry."""
    table = find_model(joint.model, protocol).table
    bits = 8 * table["present_position"].size
    return (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if table.position_signed else (0, 2**bits - 1)


def _wrong_ticks(rng: random.Random, emu: ServoEmulator, joint: JointSettings) -> int:
    """A position no reading of ``joint`` should turn into a goal."""
    lo, hi = _register_range(joint, emu.protocol)
    kind = rng.randrange(4)
    if kind == 0:  # past a limit by up to 1.5 rad
        side = rng.choice((-1.0, 1.0))
        edge = joint.max if side > 0 else joint.min
        ticks = radians_to_ticks(edge + side * rng.uniform(0.05, 1.5), joint)
    elif kind == 1:  # beyond a revolution from the zero
        ticks = joint.zero_tick + rng.choice((-1, 1)) * round(joint.ticks_per_rev * 1.5)
    elif kind == 2:  # the other end of the range, in one reply
        ticks = radians_to_ticks(rng.choice((joint.min, joint.max)), joint)
    else:  # anything at all
        ticks = rng.randint(lo, hi)
    return min(max(ticks, lo), hi)


def run(
    cycles: int,
    protocol: float = 2.0,
    seed: int = 0,
    fault_rate: float = 0.03,
    progress: Callable[[int], None] | None = None,
) -> Outcome:
    """Run ``cycles`` read periods of the bus with a fault starting in a ``fault_rate`` share
    of them (the kinds in turn, at most one of each at a time); see the module docstring."""
    rng = random.Random(seed)
    profile = load_profile(PROFILES[protocol])
    joints = {j.name: j for j in profile.joints}
    gaze = GazeSettings(enabled=True, watchdog=0.5)  # long: a loaded machine starves the pty
    out = Outcome(protocol)
    emu = ServoEmulator.for_profile(profile.joints, protocol).start()
    settings = replace(
        profile.bus,
        port=emu.port_path,
        timeout=0.05,
        stale_after=0.3,
        error_poll_interval=0.25,
        probe_interval=0.1,
        reconnect_backoff=(0.05, 0.5),
    )
    bus = DynamixelBus(settings, profile.joints, gaze=gaze)
    period = 1.0 / settings.rate
    ends: dict[str, tuple[int, Callable[[], None]]] = {}  # fault kind: (last cycle, end it)
    state = "off"
    began = time.monotonic()
    bus.start()
    try:
        while bus.latest() is None and time.monotonic() - began < 30.0:
            time.sleep(period)  # the port opened and the head read once
        bus.engage()
        tick = time.monotonic()
        for cycle in range(cycles):
            for kind, (last, end) in list(ends.items()):
                if cycle >= last:
                    end()
                    del ends[kind]
            if rng.random() < fault_rate:
                kind = FAULTS[sum(out.injected.values()) % len(FAULTS)]  # each kind in turn
                if kind not in ends:
                    ends[kind] = (cycle + rng.randint(5, 30), _start(kind, rng, emu, bus, joints))
                    out.injected[kind] += 1
            now = bus.status()["gaze"]["state"]
            if now == "stopped" and state != "stopped":
                out.stops += 1
            state = now
            if cycle % 10 == 0 and state != "on":
                bus.engage()  # as gaze does at its next look, which then asks for goals
            if cycle % 20 == 0 or (cycle % 10 == 0 and state != "on"):
                goals = {n: rng.uniform(-4.0, 4.0) for n in gaze.joints}
                bus.move(goals, rng.uniform(0.2, gaze.max_speed))
            if progress is not None:
                progress(cycle + 1)
            tick = max(tick + period, time.monotonic())  # late: the next period from now
            time.sleep(max(0.0, tick - time.monotonic()))
        out.cycles = cycles
    finally:
        for _, end in ends.values():
            end()
        out.bad_readings += bus.status()["bad_readings"]
        bus.stop()  # the torque policy (hold), the last write path
        out.seconds = time.monotonic() - began
        for name, joint in joints.items():
            taken = [ticks_to_radians(g, joint) for g in emu.goals(joint.id)]
            out.goals[name] = len(taken)
            bad = [round(a, 3) for a in taken if not joint.min <= a <= joint.max]
            if bad:
                out.outside[name] = bad
        emu.stop()
    return out


def _start(
    kind: str,
    rng: random.Random,
    emu: ServoEmulator,
    bus: DynamixelBus,
    joints: dict[str, JointSettings],
) -> Callable[[], None]:
    """Start a fault of ``kind``; what ends it."""
    joint = rng.choice(list(joints.values()))
    servo = joint.id
    if kind == "glitch":
        emu.glitch(servo, _wrong_ticks(rng, emu, joint), replies=rng.randint(1, 30))
        return lambda: None  # it ends by itself after its replies
    if kind == "corrupt":
        emu.corrupt(servo, replies=rng.randint(1, 10))
        return lambda: None
    if kind == "mute":
        emu.mute(servo)
        return lambda: emu.mute(servo, False)
    if kind == "unplug":
        emu.unplug()
        return emu.replug
    if kind == "push":  # by hand, past a limit (a held servo pulls back), then back inside
        edge, side = rng.choice(((joint.max, 1.0), (joint.min, -1.0)))
        emu.set_angle(joint.name, edge + side * rng.uniform(0.05, 0.5))
        inside = rng.uniform(joint.min, joint.max)
        return lambda: emu.set_angle(joint.name, inside)
    if kind == "error":
        emu.set_hardware_error(servo, 0x04)  # overheating, in both protocols
        return lambda: emu.set_hardware_error(servo, 0)
    if kind == "disengage":
        bus.disengage()
        return bus.engage
    if kind == "restart":
        bus.stop()
        bus.start()
        return lambda: None
    raise ValueError(f"no fault {kind!r}")
