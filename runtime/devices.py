"""The daemon's camera and servos: real hardware, or the simulated world behind the real drivers.

On a robot the camera comes from :func:`drivers.camera.open_camera` and the joint angles from a
:class:`~drivers.dynamixel.bus.DynamixelBus` on the profile's serial port. With ``--sim SCENE``
the daemon runs its own copy of the simulated world (deterministic, driven by wall-clock time
from a shared ``epoch`` so that two daemons started together see the same scene at the same
moment): the camera renders the robot's head camera, and the simulated joint angles go into a
Dynamixel emulator on a pseudo-terminal, which the real driver reads like a servo bus.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

from drivers.camera.base import FrameSource
from runtime.config import ConfigError

log = logging.getLogger("percept.devices")


class Devices:
    """The camera (a :class:`~drivers.camera.FrameSource`) and the joints (a
    :class:`~drivers.joints.JointSource`), plus whatever stands in for hardware."""

    def __init__(
        self,
        camera: Any,
        joints: Any,
        resolution: tuple[int, int],
        extras: tuple[Any, ...] = (),
        clock: SceneClock | None = None,
    ) -> None:
        self.camera = camera
        self.joints = joints
        self.resolution = resolution
        self._extras = list(extras)  # started before and stopped after the drivers
        self.clock = clock

    def start(self) -> None:
        for extra in self._extras:
            extra.start()
        self.joints.start()
        self.camera.start()

    @contextlib.contextmanager
    def calibration(self) -> Iterator[None]:
        """While the background is calibrated; in simulation the camera shows the scene's start
        (the empty floor) meanwhile, and the scene clock starts after it unless an epoch was
        given."""
        if self.clock is None:
            yield
            return
        self.clock.hold = True
        try:
            yield
        finally:
            self.clock.release()

    def close(self) -> None:
        for part in (self.camera, self.joints, *reversed(self._extras)):
            try:
                part.stop()
            except Exception as err:  # shutting down: report and go on
                log.warning("stopping %s failed: %s", type(part).__name__, err)


def open_devices(
    robot: str,
    profile: Any,
    experiment: Any,
    *,
    sim_scene: str | None = None,
    sim_epoch: float | None = None,
) -> Devices:
    """The devices of ``robot``: its profile's hardware, or the simulated world's stand-ins."""
    if sim_scene is not None:
        return _simulated(robot, profile, sim_scene, sim_epoch)
    from drivers.camera import open_camera
    from drivers.dynamixel.bus import DynamixelBus

    camera = open_camera(profile.camera)
    joints = DynamixelBus(profile.bus, profile.joints)
    log.info("camera %s, servos on %s", profile.camera.source, profile.bus.port)
    return Devices(camera, joints, (profile.camera.width, profile.camera.height))


class SceneClock:
    """Scene time from wall-clock time: ``now - epoch``, never below 0; held at 0 while
    ``hold`` (background calibration). Without an epoch, it starts when released."""

    def __init__(self, epoch: float | None) -> None:
        self.epoch = epoch
        self.hold = False

    def release(self) -> None:
        self.hold = False
        if self.epoch is None:
            self.epoch = time.time()

    def now(self) -> float:
        if self.hold or self.epoch is None:
            return 0.0
        return max(0.0, time.time() - self.epoch)


def _simulated(robot: str, profile: Any, scene: str, epoch: float | None) -> Devices:
    from drivers.dynamixel.bus import DynamixelBus
    from drivers.dynamixel.emulator import ServoEmulator
    from runtime.scene import open_world

    world = open_world(scene)
    if robot not in world.robots:
        raise ConfigError(scene, "robots", f"the scene has no robot {robot!r} ({world.robots})")
    clock = SceneClock(epoch)
    emulator = ServoEmulator.for_profile(profile.joints, profile.bus.protocol)
    bridge = _JointBridge(world, robot, emulator, clock, profile.bus.rate)
    camera = _SimCamera(world, robot, replace(profile.camera, source="sim"), clock)
    bus = DynamixelBus(replace(profile.bus, port=emulator.port_path), profile.joints)
    log.info(
        "simulated scene %s as robot %s; servos emulated on %s", scene, robot, emulator.port_path
    )
    return Devices(
        camera,
        bus,
        (profile.camera.width, profile.camera.height),
        extras=(emulator, bridge),
        clock=clock,
    )


class _SimCamera(FrameSource):
    """The robot's head camera in the simulated world, rendered at the scene clock's time and
    paced at the profile's frame rate."""

    def __init__(self, world: Any, robot: str, settings: Any, clock: SceneClock) -> None:
        super().__init__(settings)
        self._world, self._robot, self._clock = world, robot, clock

    def _open(self) -> None:
        pass

    def _read(self) -> Any:
        return self._world.render(self._robot, self._clock.now())

    def _close(self) -> None:
        # The renderer's GL context belongs to this (the reader) thread: free it here, at the end.
        if self._stopping.is_set():
            self._world.close()


class _JointBridge:
    """Pushes the simulated joint angles into the servo emulator ``rate`` times a second, so
    that the real driver reads them from the emulated bus."""

    def __init__(self, world: Any, robot: str, emulator: Any, clock: SceneClock, rate: float):
        self._world, self._robot, self._emulator, self._clock = world, robot, emulator, clock
        self._period = 1.0 / rate
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sim joints", daemon=True)

    def start(self) -> None:
        self._push()  # the first reading is right from the start
        self._thread.start()

    def _push(self) -> None:
        for joint, angle in self._world.joint_angles(self._robot, self._clock.now()).items():
            if joint in self._emulator.joints:
                self._emulator.set_angle(joint, angle)

    def _run(self) -> None:
        while not self._stop.wait(self._period):
            self._push()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(1.0)
