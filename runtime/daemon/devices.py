"""The daemon's camera and servos: real hardware, or the simulated world behind the real drivers.

On a robot the camera comes from :func:`percept.drivers.camera.open_camera` and the joint angles
from a :class:`~percept.drivers.dynamixel.bus.DynamixelBus` on the profile's serial port. With
``--sim SCENE`` the daemon runs its own copy of the simulated world (deterministic, driven by
wall-clock time from a shared ``epoch`` so that two daemons started together see the same scene at
the same moment): the camera renders the robot's head camera, and the simulated joint angles go into
a Dynamixel emulator on a pseudo-terminal, which the real driver reads like a servo bus (the
experiment's ``[sim]`` table: ``joints = "emulator"``, pushed ``push_rate`` times a second), or
straight to the daemon (``joints = "direct"``). With the experiment's ``[gaze]`` enabled the
bus may move the head; in simulation the simulated head then follows the emulated servos.

The background calibration wants the empty floor. A scene whose robot keeps its head still while
the floor is empty is held at scene time 0 during the calibration (as long as it takes); one
whose robot's head moves then (a sweep over its working range, keyframes on the head joints)
lets scene time run, and the calibration takes its frames spread over that sweep
(:attr:`Devices.sweep`, :meth:`Devices.wanted`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from dataclasses import replace
from typing import TYPE_CHECKING, Protocol

from percept.config.loader import ConfigError

if TYPE_CHECKING:
    from percept.drivers.camera.base import FrameSource
    from percept.drivers.dynamixel.settings import GazeSettings
    from percept.drivers.joints import JointSource
    from percept.drivers.sim.clock import WallClock
    from percept.drivers.sim.model import RobotPlatform
    from percept.drivers.sim.scene import Scene
    from percept.drivers.sim.settings import SimSettings
    from percept.drivers.sim.world import SimWorld
    from percept.runtime.settings.experiment import Experiment
    from percept.runtime.settings.profile import PlatformProfile

log = logging.getLogger("percept.devices")

EMULATED_SERVOS = "percept.sim.emulated_servos"
"""The logger of the driver reading the servo emulator: its stale joints are the emulator's
late replies (a starved thread on a busy machine), not hardware faults."""


class StandIn(Protocol):
    """Something that stands in for hardware (the servo emulator, the world's feeder of it)."""

    def start(self) -> object: ...

    def stop(self) -> None: ...


class Devices:
    """The camera (a :class:`~percept.drivers.camera.FrameSource`) and the joints (a
    :class:`~percept.drivers.joints.JointSource`), plus whatever stands in for hardware."""

    def __init__(
        self,
        camera: FrameSource,
        joints: JointSource,
        resolution: tuple[int, int],
        extras: tuple[StandIn, ...] = (),
        clock: WallClock | None = None,
        world: SimWorld | None = None,
        emulated_servos: bool = False,
        sweep: float = 0.0,
    ) -> None:
        self.camera = camera
        self.joints = joints
        self.resolution = resolution
        self._extras = list(extras)  # started before and stopped after the drivers
        self.clock = clock
        self._world = world  # the simulated world: its renderers are freed last
        self.emulated_servos = emulated_servos  # joints read from the servo emulator
        self.sweep = sweep
        """Scene seconds the simulated head sweeps over the empty floor at the start (0: it
        holds still then, or no simulation): see :func:`head_sweep`."""

    @property
    def stand_ins(self) -> tuple[StandIn, ...]:
        """What stands in for hardware (in simulation: the servo emulator and its feeder);
        tests inject faults through them."""
        return tuple(self._extras)

    def start(self) -> None:
        for extra in self._extras:
            extra.start()
        self.joints.start()
        self.camera.start()

    @contextlib.contextmanager
    def calibration(self) -> Iterator[None]:
        """While the background is calibrated. In simulation the camera shows the scene's start
        (the empty floor) meanwhile, and the scene clock starts after it unless an epoch was
        given; with a :attr:`sweep` the clock starts at the first calibration frame instead
        (:meth:`start_sweep`), so that the head sweeps while the floor is empty."""
        if self.clock is None:
            yield
            return
        self.clock.hold = True
        try:
            yield
        finally:
            self.clock.release()

    def start_sweep(self) -> None:
        """The calibration has its first frame: with a :attr:`sweep`, the scene's time runs from
        now on (from the epoch, if one was given). Waiting for it keeps a camera that is slow
        to start (the renderer's first frame) from missing the sweep."""
        if self.sweep > 0 and self.clock is not None and self.clock.hold:
            self.clock.release()

    def wanted(self, t: float, taken: int, needed: int) -> bool:
        """Whether the frame taken at monotonic time ``t`` is a calibration frame, ``taken`` of
        ``needed`` being taken: every frame of a still head; during a :attr:`sweep` the first
        frame at or after each ``sweep / needed`` seconds of scene time, so that the calibration
        sees the whole sweep."""
        if self.sweep <= 0 or self.clock is None:
            return True
        return self.clock.at(t) >= taken * self.sweep / needed

    def close(self) -> None:
        parts: tuple[StandIn, ...] = (self.camera, self.joints, *reversed(self._extras))
        for part in parts:
            try:
                part.stop()
            except Exception as err:  # shutting down: report and go on
                log.warning("stopping %s failed: %s", type(part).__name__, err)
        if self._world is not None:
            self._world.close()


def open_devices(
    robot: str,
    profile: PlatformProfile,
    experiment: Experiment,
    *,
    sim_scene: str | None = None,
    sim_epoch: float | None = None,
) -> Devices:
    """The devices of ``robot``: its profile's hardware, or the simulated world's stand-ins."""
    gaze = experiment.gaze if experiment.gaze.enabled else None
    if sim_scene is not None:
        return _simulated(robot, profile, experiment.sim, sim_scene, sim_epoch, gaze)
    from percept.drivers.camera import open_camera
    from percept.drivers.dynamixel.bus import DynamixelBus
    from percept.perception.segmentation.labelling.regions import grid_step

    # Frames at the size perception works on, where the camera can give them (a folder of
    # JPEG files, a raw YUYV camera): the full image is made only for what needs it.
    width, height = profile.camera.width, profile.camera.height
    camera = open_camera(
        profile.camera, grid_step(width, height, experiment.perception.regions.grid_pixels)
    )
    joints = DynamixelBus(profile.bus, profile.joints, gaze=gaze)
    log.info("camera %s, servos on %s", profile.camera.source, profile.bus.port)
    return Devices(camera, joints, (profile.camera.width, profile.camera.height))


def _simulated(
    robot: str,
    profile: PlatformProfile,
    sim: SimSettings,
    scene: str,
    epoch: float | None,
    gaze: GazeSettings | None,
) -> Devices:
    from percept.drivers.sim.camera import SimCamera
    from percept.drivers.sim.clock import WallClock
    from percept.runtime.settings.scene import open_world

    world = open_world(scene)
    try:
        _check_robot(world, robot, profile, scene)
        clock = WallClock(epoch, period=world.scene.duration if sim.loop else None)
        # With gaze the head follows the servos, not the scene: the scene's sweep is not played.
        sweep = head_sweep(world.scene, robot) if gaze is None else 0.0
        camera = SimCamera(world, robot, replace(profile.camera, source="sim"), clock)
        if sim.joints == "direct" and gaze is not None:
            raise ValueError('gaze moves servos: it needs [sim] joints = "emulator"')
        if sim.joints == "direct":
            from percept.drivers.sim.joints import SimJoints

            joints: JointSource = SimJoints(world, robot, clock)
            extras: tuple[StandIn, ...] = ()
            where = "read directly"
        else:
            from percept.drivers.dynamixel.bus import DynamixelBus
            from percept.drivers.dynamixel.emulator import ServoEmulator
            from percept.drivers.sim.joints import EmulatorBridge

            emulator = ServoEmulator.for_profile(profile.joints, profile.bus.protocol)
            follow = gaze.joints if gaze is not None else ()
            bridge = EmulatorBridge(world, robot, emulator, clock, sim.push_rate, follow)
            joints = DynamixelBus(
                replace(profile.bus, port=emulator.port_path),
                profile.joints,
                logger=EMULATED_SERVOS,
                gaze=gaze,
                emulated=True,
            )
            extras = (emulator, bridge)
            where = f"emulated on {emulator.port_path}"
    except BaseException:
        world.close()
        raise
    log.info("simulated %s as robot %s; servos %s", scene, robot, where)
    return Devices(
        camera,
        joints,
        (profile.camera.width, profile.camera.height),
        extras=extras,
        clock=clock,
        world=world,
        emulated_servos=sim.joints == "emulator",
        sweep=sweep,
    )


def head_sweep(scene: Scene, robot: str, step: float = 0.01) -> float:
    """The scene seconds at the start in which the floor is empty and ``robot``'s head moves (the
    background calibration's sweep): from 0 to the first object's arrival when some joint of the
    robot moves by more than a micro-radian in that time (looked at every ``step`` seconds), else
    0 (its head holds still then, or objects are there from the start)."""
    import numpy as np

    if any(o.present for o in scene.objects):
        return 0.0
    empty = min((e.t for e in scene.timeline if e.action == "add"), default=scene.duration)
    times = np.arange(0.0, empty + step, step).clip(max=empty)
    for motion in scene.robot(robot).joints.values():
        angles = [motion.angle(float(t)) for t in times]
        if max(angles) - min(angles) > 1e-6:
            return float(empty)
    return 0.0


def _check_robot(world: SimWorld, robot: str, profile: PlatformProfile, scene: str) -> None:
    """The daemon's profile must have the camera and the kinematic chain the scene simulates its
    robot with: the world renders at that camera's resolution and moves that chain."""
    if robot not in world.robots:
        raise ConfigError(scene, "robots", f"the scene has no robot {robot!r} ({world.robots})")
    simulated = world.robot_model(robot).platform

    def seen(p: RobotPlatform) -> tuple[object, ...]:
        return p.camera.width, p.camera.height, p.camera.lens, p.kinematics

    if seen(simulated) != seen(profile):
        index = world.robots.index(robot)
        raise ConfigError(
            scene,
            f"robots[{index}].profile",
            f"robot {robot!r} is simulated with the camera and chain of {simulated.name!r} "
            f"({simulated.camera.width}x{simulated.camera.height} camera), the daemon was given "
            f"{profile.name!r} ({profile.camera.width}x{profile.camera.height}): run it with "
            f"--robot set to the scene's profile",
        )
