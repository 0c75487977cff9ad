"""Simulated joint angles: read directly (:class:`SimJoints`), or pushed into a Dynamixel
emulator (:class:`EmulatorBridge`) so that the real driver reads them off an emulated bus.

With gaze the bridge works the other way round for the joints the driver moves: the emulated
servos move towards the goals the driver writes, and the simulated head follows them, so the
camera sees what the servo bytes did (the loop closed through the real protocol)."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from typing import Any, Protocol

from percept.drivers.joints import JointSample
from percept.drivers.sim.clock import SceneClock
from percept.drivers.sim.world import SimWorld

log = logging.getLogger("percept.sim")


class AngleSink(Protocol):
    """Where the bridge puts angles: ``percept.drivers.dynamixel.emulator.ServoEmulator``."""

    joints: dict[str, Any]

    def set_angle(self, joint: str, radians: float) -> None: ...

    def angle(self, joint: str) -> float: ...


class SimJoints:
    """A :class:`percept.drivers.joints.JointSource` with the simulated robot's exact joint angles.

    ``angles_at(t)`` gives every movable joint's angle at the scene time ``clock`` had at
    monotonic time ``t``: no quantisation, no delay, age 0.
    """

    def __init__(self, world: SimWorld, robot: str, clock: SceneClock) -> None:
        world.scene.robot(robot)  # raises KeyError naming the robots there are
        self.world = world
        self.robot = robot
        self.clock = clock
        self._running = False

    def start(self) -> None:
        self._running = True

    def stop(self) -> None:
        self._running = False

    def angles_at(self, t: float) -> JointSample | None:
        if not self._running:
            return None
        angles = self.world.joint_readings(self.robot, self.clock.at(t))
        return JointSample(angles=angles, t=t, age=0.0, stale=frozenset())

    def status(self) -> dict[str, Any]:
        return {
            "state": "connected" if self._running else "stopped",
            "source": "sim",
            "stale": [],
            "errors": {},
            "reads_per_s": 0.0,
            "retries": 0,
            "reconnects": 0,
        }


class EmulatorBridge:
    """Pushes robot ``robot``'s simulated joint angles into ``emulator`` ``rate`` times a second
    (scene time from ``clock``), so a :class:`~percept.drivers.dynamixel.bus.DynamixelBus` on the
    emulator's port reads them like servo encoders. Joints without a servo are left out.

    The ``follow`` joints (those gaze moves) start where the scene has them at its start (scene
    time 0) and from then on go the other way: the world takes their angles from the emulated
    servos."""

    def __init__(
        self,
        world: SimWorld,
        robot: str,
        emulator: AngleSink,
        clock: SceneClock,
        rate: float = 200.0,
        follow: Sequence[str] = (),
    ) -> None:
        if rate <= 0:
            raise ValueError(f"rate must be positive, got {rate}")
        unknown = [j for j in follow if j not in emulator.joints]
        if unknown:
            raise ValueError(f"cannot follow joint(s) without a servo: {', '.join(unknown)}")
        self.world = world
        self.robot = robot
        self.emulator = emulator
        self.clock = clock
        self.follow = tuple(follow)
        self._period = 1.0 / rate
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def push(self, scene_time: float) -> dict[str, float]:
        """Set the servos to the angles at ``scene_time`` now (but for the followed joints),
        and the followed joints of the world to their servos; the angles set on servos."""
        angles = {
            joint: angle
            for joint, angle in self.world.joint_readings(self.robot, scene_time).items()
            if joint in self.emulator.joints and joint not in self.follow
        }
        for joint, angle in angles.items():
            self.emulator.set_angle(joint, angle)
        if self.follow:
            self.world.follow(self.robot, {j: self.emulator.angle(j) for j in self.follow})
        return angles

    def start(self) -> None:
        """Put the followed joints where the scene starts (scene time 0), push once at once,
        then keep pushing in a background thread."""
        if self._thread is not None:
            return
        # The scene's start, not the scene as it is now: the scene's time runs from an epoch
        # while the daemon starts (3-15 s, with the load), and the head taken from its keyframes
        # then was anywhere in their sweep (0.3-0.6 rad aside in demos with gaze): the
        # calibration sweep came back there and every look of the games too.
        start = self.world.joint_readings(self.robot, 0.0)
        for joint in self.follow:
            self.emulator.set_angle(joint, start[joint])
        self.push(self.clock.at(time.monotonic()))
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="percept-sim-joints", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self._period):
            try:
                self.push(self.clock.at(time.monotonic()))
            except ValueError as err:  # an angle beyond the encoder's range: say so, go on
                log.warning("sim joints: %s", err)

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(1.0)
            self._thread = None
