"""The simulated head camera: a :class:`~drivers.camera.base.FrameSource` whose frames are
rendered from the robot's head camera in the simulated world."""

from __future__ import annotations

import time

import numpy as np

from drivers.camera.base import FrameSource
from drivers.camera.settings import CameraSettings
from drivers.sim.clock import SceneClock, StepClock
from drivers.sim.world import SimWorld


class SimCamera(FrameSource):
    """Robot ``robot``'s head camera in ``world``, at the scene time ``clock`` gives.

    Paced like any non-live source by ``settings.pace`` and ``settings.fps``. With a
    :class:`~drivers.sim.clock.StepClock` (the default) frame k shows scene time k / fps; with a
    :class:`~drivers.sim.clock.WallClock` it shows the scene as it is at the moment of capture.
    Frame times are the monotonic time the render began.
    """

    def __init__(
        self,
        world: SimWorld,
        robot: str,
        settings: CameraSettings,
        clock: SceneClock | None = None,
    ) -> None:
        super().__init__(settings)
        if robot not in world.robots:
            raise KeyError(f"the scene has no robot {robot!r} (it has {', '.join(world.robots)})")
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
        self.scene_time = 0.0
        """Scene time of the newest frame."""

    def _open(self) -> None:
        pass

    def _read(self) -> np.ndarray:
        self._taken = time.monotonic()
        self.scene_time = self.clock.next_frame(1.0 / self.settings.fps, self._taken)
        return self.world.render(self.robot, self.scene_time)

    def _frame_time(self) -> float:
        return self._taken

    def _close(self) -> None:
        pass

    def __repr__(self) -> str:
        return f"SimCamera({self.world.scene.name!r}, {self.robot!r})"
