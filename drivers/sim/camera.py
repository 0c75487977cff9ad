"""The simulated head camera: a :class:`~percept.drivers.camera.base.FrameSource` whose frames are
rendered from the robot's head camera in the simulated world, with the faults of a real camera
on demand (it stops delivering, or its cable is pulled)."""

from __future__ import annotations

import threading
import time

import numpy as np

from percept.drivers.camera.base import FrameSource
from percept.drivers.camera.settings import CameraSettings
from percept.drivers.sim.clock import SceneClock, StepClock
from percept.drivers.sim.world import SimWorld


class SimCamera(FrameSource):
    """Robot ``robot``'s head camera in ``world``, at the scene time ``clock`` gives.

    Paced like any non-live source by ``settings.pace`` and ``settings.fps``. With a
    :class:`~percept.drivers.sim.clock.StepClock` (the default) frame k shows scene time k / fps;
    with a :class:`~percept.drivers.sim.clock.WallClock` it shows the scene as it is at the moment
    of capture. Frame times are the monotonic time the render began.

    Faults, for tests of what uses a camera: :meth:`stall` (reads block, as a camera that stops
    delivering) and :meth:`unplug` (opens and reads fail, as a pulled cable) until
    :meth:`resume` or :meth:`replug`.
    """

    def __init__(
        self,
        world: SimWorld,
        robot: str,
        settings: CameraSettings,
        clock: SceneClock | None = None,
    ) -> None:
        super().__init__(settings)
        world.scene.robot(robot)  # raises KeyError naming the robots there are
        lens = world.camera_model(robot)
        if (settings.width, settings.height) != (lens.width, lens.height):
            raise ValueError(
                f"camera settings ask for {settings.width}x{settings.height}, the simulated "
                f"camera of {robot} renders {lens.width}x{lens.height}"
            )
        self.world = world
        self.robot = robot
        self.clock: SceneClock = clock if clock is not None else StepClock()
        self._taken = time.monotonic()
        self._flowing = threading.Event()
        self._flowing.set()
        self._plugged = threading.Event()
        self._plugged.set()

    def stall(self) -> None:
        """Stop delivering: reads block (and end only when the camera stops) until resumed."""
        self._flowing.clear()

    def resume(self) -> None:
        """Deliver frames again after :meth:`stall`."""
        self._flowing.set()

    def unplug(self) -> None:
        """The cable is pulled: reads and opens fail until :meth:`replug`."""
        self._plugged.clear()

    def replug(self) -> None:
        """The cable is back: the reader's next reconnect attempt succeeds."""
        self._plugged.set()

    def _open(self) -> None:
        if not self._plugged.is_set():
            raise OSError("no such device (unplugged)")

    def _read(self) -> np.ndarray | None:
        while not self._flowing.wait(0.05):
            if self._stopping.is_set():
                return None
        if not self._plugged.is_set():
            raise OSError("device disconnected (unplugged)")
        self._taken = time.monotonic()
        scene_time = self.clock.next_frame(1.0 / self.settings.fps, self._taken)
        return self.world.render(self.robot, scene_time)

    def _frame_time(self) -> float:
        return self._taken

    def _close(self) -> None:
        pass

    def __repr__(self) -> str:
        return f"SimCamera({self.world.scene.name!r}, {self.robot!r})"
