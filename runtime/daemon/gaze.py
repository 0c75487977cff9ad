"""Gaze behaviours: look at a point, sweep the working range, scan fixations, look at the peer.

A :class:`Gaze` turns targets in the robot's ground frame into goal angles of the gaze joints
(inverse kinematics of the head chain, :func:`percept.kinematics.gaze.look_at`) and hands them
to the servo bus, which clips them to the joint limits, sends them and stops on faults
(:class:`~percept.drivers.dynamixel.bus.DynamixelBus`). The behaviours that take time (sweep,
scan) are lists of fixations run one after the other, each held until the head has settled and
then for a dwell time, so the caller decides on which thread they run and stops them with an
event.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from percept.config.loader import ConfigError
from percept.drivers.dynamixel.settings import GazeSettings, JointSettings
from percept.drivers.joints import JointSample
from percept.kinematics.gaze import Limits, Unreachable, look_at, sweep_grid
from percept.kinematics.tree import KinematicTree
from percept.perception.warm import wait_warmed
from percept.runtime.net.codec import JSON

Vec3 = tuple[float, float, float]

log = logging.getLogger("percept.gaze")

SETTLED = math.radians(0.2)
"""A joint within this of its goal has arrived (a tick of a 4096-tick encoder is 0.09 deg)."""

SWEEP_STEPS = 5
"""Fixations of the calibration sweep across the pan range (one more brings the head back)."""
SWEEP_DWELL = 0.3
"""Seconds the calibration sweep holds each fixation."""
SWEEP_TRIES = 4
"""Times the calibration sweep tries a fixation (or the turn back) that gaze gave up on."""
SWEEP_RETRY_PAUSE = 0.5
"""Seconds before it tries again: a stale joint (a late servo reply) answers again by then."""
SWEEP_LIMIT = 60.0
"""Seconds a calibration sweep may take at most: the daemon has no world model meanwhile, so a
longer one (a very low ``max_speed``) is refused when the daemon starts."""


def sweep_seconds(pan: JointSettings, max_speed: float) -> float:
    """Seconds the calibration sweep takes at ``max_speed`` from anywhere inside the pan
    joint's limits: to one end, across to the other, back to where it was (twice the range),
    holding each fixation :data:`SWEEP_DWELL` seconds."""
    return 2.0 * (pan.max - pan.min) / max_speed + (SWEEP_STEPS + 1) * SWEEP_DWELL


def check_sweep(path: str | Path, gaze: GazeSettings, joints: Sequence[JointSettings]) -> None:
    """Refuse, before anything starts, a calibration sweep longer than :data:`SWEEP_LIMIT`;
    raises :class:`~percept.config.loader.ConfigError` naming ``path`` and ``gaze.max_speed``."""
    pan = next(j for j in joints if j.name == gaze.joints[0])
    seconds = sweep_seconds(pan, gaze.max_speed)
    if seconds > SWEEP_LIMIT:
        fastest = 2.0 * (pan.max - pan.min) / (SWEEP_LIMIT - (SWEEP_STEPS + 1) * SWEEP_DWELL)
        raise ConfigError(
            path,
            "gaze.max_speed",
            f"{gaze.max_speed:g} rad/s makes the background calibration's sweep of {pan.name} "
            f"take {seconds:.0f} s, with no world model meanwhile (at most {SWEEP_LIMIT:g} s: "
            f"a max_speed of {math.ceil(fastest * 100) / 100:g} rad/s or more, or --background "
            "with a saved model)",
        )


class Head(Protocol):
    """What gaze needs of the servo bus (:class:`~percept.drivers.dynamixel.bus.DynamixelBus`)."""

    def engage(self) -> None: ...

    def disengage(self) -> None: ...

    def move(self, goals: Mapping[str, float], speed: float | None = None) -> dict[str, float]: ...

    def latest(self) -> JointSample | None: ...

    def status(self) -> dict[str, Any]: ...  # as DynamixelBus.status() gives it


@dataclass(frozen=True)
class Fixation:
    """One place to look: joint goals, and the ground point they face if there is one."""

    goals: dict[str, float]
    target: Vec3 | None = None


class Gaze:
    """The gaze behaviours of one robot over its servo bus ``head``; see the module docstring.

    ``joints`` are the profile's servos (their limits bound the inverse kinematics as the bus
    bounds the writes); ``settings`` the experiment's ``[gaze]`` table.
    """

    def __init__(
        self,
        head: Head,
        tree: KinematicTree,
        joints: Sequence[JointSettings],
        settings: GazeSettings,
    ) -> None:
        by_name = {j.name: j for j in joints}
        self.head = head
        self.tree = tree
        self.settings = settings
        self.limits = {n: Limits(by_name[n].min, by_name[n].max) for n in settings.joints}
        self._lock = threading.Lock()
        self._target: Vec3 | None = None
        self._behaviour = "idle"
        self._goals: dict[str, float] = {}
        self._refused: str | None = None

    # -- one look -------------------------------------------------------------------------------

    def aim(self, target: Vec3) -> dict[str, float]:
        """The goal angles that face ``target`` (ground frame, metres) from where the other
        joints are now; raises :class:`~percept.kinematics.gaze.Unreachable`."""
        sample = self.head.latest()
        return look_at(self.tree, target, self.limits, sample.angles if sample else None)

    def look_at(
        self, x: float, y: float, z: float = 0.0, speed: float | None = None
    ) -> dict[str, float]:
        """Turn the head so that the optical axis goes through (x, y, z); the goals sent.
        A target the head cannot face raises :class:`Unreachable` and nothing moves."""
        target = (float(x), float(y), float(z))
        try:
            goals = self.aim(target)
        except Unreachable as err:
            with self._lock:
                self._refused = str(err)
            raise
        return self._go(Fixation(goals, target), "look_at", speed)

    def look_at_peer(
        self, x: float, y: float, height: float | None = None, speed: float | None = None
    ) -> dict[str, float]:
        """Look at the peer robot standing at (x, y) of this robot's ground frame, at the
        height of its camera (default: this robot's camera height with its head level)."""
        z = self.eye_height() if height is None else height
        return self.look_at(x, y, z, speed)

    def knows_head(self) -> bool:
        """Whether the bus has read every gaze joint (a servo may not answer at first)."""
        sample = self.head.latest()
        return sample is not None and all(n in sample.angles for n in self.limits)

    def eye_height(self) -> float:
        """This robot's camera height above the ground with the gaze joints at 0."""
        sample = self.head.latest()
        angles = {**(sample.angles if sample else {}), **dict.fromkeys(self.limits, 0.0)}
        return float(self.tree.camera_pose(angles).t[2])

    def _go(self, fixation: Fixation, behaviour: str, speed: float | None) -> dict[str, float]:
        if self._bus_state() != "on":
            self.head.engage()
        sent = self.head.move(fixation.goals, speed)
        with self._lock:
            self._target, self._behaviour, self._goals = fixation.target, behaviour, sent
            self._refused = None
        return sent

    def _bus_state(self) -> str:
        return str(self.head.status().get("gaze", {}).get("state", "off"))

    # -- over time ------------------------------------------------------------------------------

    def settled(self, tolerance: float = SETTLED) -> bool:
        """Whether every gaze joint is within ``tolerance`` of its goal."""
        sample = self.head.latest()
        with self._lock:
            goals = dict(self._goals)
        if sample is None or not goals:
            return False
        return all(
            n in sample.angles and abs(sample.angles[n] - g) <= tolerance for n, g in goals.items()
        )

    def wait_settled(self, timeout: float, stop: threading.Event | None = None) -> bool:
        """Wait until :meth:`settled` (True), ``timeout`` seconds pass, gaze stops on a fault
        or ``stop`` is set (False)."""
        stop = stop or threading.Event()
        end = time.monotonic() + timeout
        while time.monotonic() < end and not stop.is_set():
            if self.settled():
                return True
            if self._bus_state() == "stopped":
                return False
            stop.wait(0.01)
        return self.settled()

    def run(
        self,
        fixations: Sequence[Fixation],
        dwell: float,
        stop: threading.Event,
        behaviour: str,
        speed: float | None = None,
    ) -> int:
        """Look at each fixation in turn until settled, then for ``dwell`` seconds; the number
        reached. Ends early when ``stop`` is set or gaze stops on a fault."""
        reached = 0
        for fixation in fixations:
            if stop.is_set():
                break
            self._go(fixation, behaviour, speed)
            if not self.wait_settled(self.travel_time(fixation.goals) + 1.0, stop):
                break
            reached += 1
            stop.wait(dwell)
        with self._lock:
            self._behaviour = "idle"
        return reached

    def travel_time(self, goals: Mapping[str, float]) -> float:
        """Seconds the slowest joint needs from where it is to its goal at the gaze speed."""
        sample = self.head.latest()
        here = sample.angles if sample else {}
        gaps = [abs(g - here.get(n, g)) for n, g in goals.items()]
        return max(gaps, default=0.0) / self.settings.max_speed

    # -- behaviours as fixations ----------------------------------------------------------------

    def sweep(
        self,
        pan: tuple[float, float] | None = None,
        tilt: tuple[float, float] | None = None,
        steps: tuple[int, int] = (5, 3),
    ) -> list[Fixation]:
        """The calibration sweep: a grid of head poses over the working range (default: each
        joint's whole range), row by row, back and forth so the head never jumps across it.
        The first gaze joint pans, the second tilts
        (:func:`~percept.kinematics.gaze.sweep_grid`)."""
        return [Fixation(goals) for goals in sweep_grid(self.limits, pan, tilt, steps)]

    def calibration_sweep(self, steps: int = SWEEP_STEPS) -> list[Fixation]:
        """The background calibration's sweep: the first gaze joint (pan) over its whole range
        in ``steps`` fixations, the others where they are, then back to where the head was."""
        sample = self.head.latest()
        here = dict(sample.angles) if sample else {}
        names = list(self.limits)
        level = here.get(names[1], 0.0) if len(names) > 1 else 0.0
        fixations = self.sweep(tilt=(level, level), steps=(steps, 1))
        fixations.append(Fixation({n: here.get(n, 0.0) for n in names}))
        return fixations

    def run_time(self, fixations: Sequence[Fixation], dwell: float) -> float:
        """Seconds :meth:`run` takes over ``fixations`` from where the head is, at the gaze
        speed and without settling time."""
        sample = self.head.latest()
        here = dict(sample.angles) if sample else {}
        total = 0.0
        for fixation in fixations:
            gaps = [abs(g - here.get(n, g)) for n, g in fixation.goals.items()]
            total += max(gaps, default=0.0) / self.settings.max_speed + dwell
            here.update(fixation.goals)
        return total

    def scan(self, points: Sequence[Vec3]) -> tuple[list[Fixation], list[str]]:
        """Fixations on ground points in the order given; the points the head cannot face are
        left out, with the reasons."""
        fixations, refused = [], []
        for point in points:
            try:
                fixations.append(Fixation(self.aim(point), point))
            except Unreachable as err:
                refused.append(str(err))
        return fixations, refused

    # -- status ---------------------------------------------------------------------------------

    def status(self) -> dict[str, JSON]:
        """The status's ``gaze``: whether enabled, the bus's gaze state, what is looked at."""
        bus = self.head.status().get("gaze", {})
        settled = self.settled()
        with self._lock:
            return {
                "enabled": self.settings.enabled,
                "state": bus.get("state", "off"),
                "problem": bus.get("problem"),
                "behaviour": self._behaviour,
                "target": list(self._target) if self._target is not None else None,
                "goals": dict(self._goals),
                "settled": settled,
                "refused": self._refused,
            }


class CalibrationSweep:
    """The calibration sweep (:meth:`Gaze.calibration_sweep`) run on a thread of its own while
    the background is calibrated, and the pace of the calibration frames over it (:meth:`wanted`),
    so that the calibration sees the whole sweep. It is planned from where the head is, once the
    bus has read every gaze joint (planned from a joint not read yet, the sweep would move it to
    0 and leave it there)."""

    def __init__(self, gaze: Gaze, dwell: float = SWEEP_DWELL) -> None:
        self._gaze = gaze
        self._dwell = dwell
        self._stop = threading.Event()
        self._planned = threading.Event()
        self._thread = threading.Thread(target=self._run, name="gaze-sweep", daemon=True)
        self.fixations: list[Fixation] = []
        self.duration = 0.0
        """Seconds the sweep should take (:meth:`Gaze.run_time`), once planned."""
        self.began = 0.0
        self.reached = 0
        """Fixations reached so far."""

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        while not self._gaze.knows_head():
            if self._stop.wait(0.01):
                return
        # Loading the kernels (percept run's warm-up, on a thread) keeps the servo bus's thread
        # from the interpreter for up to a second at a time: the bus watchdog would stop the head
        # just engaged (it did at every start of the demo with gaze).
        if not wait_warmed(self._stop):
            return
        self.fixations = self._gaze.calibration_sweep()
        self.duration = self._gaze.run_time(self.fixations, self._dwell)
        self.began = time.monotonic()
        self._planned.set()
        log.info("the head sweeps its pan range for %.1f s (gaze)", self.duration)
        for fixation in self.fixations:
            if self._fixate(fixation, self._dwell, self._stop):
                self.reached += 1
            elif self._stop.is_set():
                return

    def _fixate(self, fixation: Fixation, dwell: float, stop: threading.Event) -> bool:
        """Look at ``fixation`` (then ``dwell`` s); whether it was reached. One that gaze gave
        up on (a stale joint: a late servo reply) is tried again after a pause, as a new look
        re-engages the head once the fault is gone, up to :data:`SWEEP_TRIES` times."""
        for _ in range(SWEEP_TRIES):
            if stop.is_set():
                return False
            if self._gaze.run([fixation], dwell, stop, "sweep"):
                return True
            stop.wait(SWEEP_RETRY_PAUSE)
        return False

    def wanted(self, t: float, taken: int, needed: int) -> bool:
        """Whether the frame taken at monotonic time ``t`` is a calibration frame, ``taken`` of
        ``needed`` being taken: none before the sweep is planned, then one per ``duration /
        needed`` seconds, but never ahead of the head while the sweep runs (a fixation tried
        again takes longer than planned)."""
        if not self._planned.is_set() or t - self.began < taken * self.duration / needed:
            return False
        ahead = taken >= needed * (self.reached + 1) / len(self.fixations)
        return not (ahead and self._thread.is_alive())

    def finish(self, stop: threading.Event) -> None:
        """Wait until the head is back where it was (or ``stop`` is set, or twice the planned
        time has passed), then end the sweep; a sweep cut short turns the head back to where
        it was."""
        end = self.began + 2 * self.duration + 1.0
        while (
            self._planned.is_set()
            and self._thread.is_alive()
            and not stop.is_set()
            and time.monotonic() < end
        ):
            self._thread.join(0.05)
        self._stop.set()
        self._thread.join(1.0)
        if self.reached < len(self.fixations) and not stop.is_set() and not self._thread.is_alive():
            # Fixations tried again on a busy machine (a bus watchdog, a late reply) can take
            # the sweep past its time: left there, the head would look aside for the whole run.
            # The turn back is tried again as the fixations are: the fault that cut the sweep
            # short is often still there (tried once, a head was left at pan 1.0, no object in
            # view and no game played, for a whole demo).
            log.warning(
                "the calibration sweep reached %d of %d fixations in its time: the head turns "
                "back to where it was",
                self.reached,
                len(self.fixations),
            )
            if not self._fixate(self.fixations[-1], 0.0, stop) and not stop.is_set():
                log.warning("the head could not be turned back: %s", self._gaze.status()["problem"])
