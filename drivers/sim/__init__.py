"""The simulated world: robots, objects and marker boxes in MuJoCo, with ground truth.

A scene file (``config/scenes/*.toml``, see :mod:`percept.drivers.sim.scene`) describes the floor,
the light, the robots with their platform profiles and head motion, the objects and carton boxes,
and what the experimenter does over time. :class:`~percept.drivers.sim.world.SimWorld` renders each
robot's head camera at any scene time and knows the truth; :mod:`percept.drivers.sim.camera` and
:mod:`percept.drivers.sim.joints` put it behind the same interfaces as the real camera and servos.

MuJoCo renders headless through EGL unless ``MUJOCO_GL`` says otherwise (``osmesa``, ``glfw``).
"""

from __future__ import annotations

import logging
import os

from percept.config.extras import require

os.environ.setdefault("MUJOCO_GL", "egl")
# PyOpenGL (under MuJoCo's EGL context) announces at INFO that an optional speed-up is missing
logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.WARNING)


def require_mujoco() -> None:
    """Fail now, as the import itself would, when MuJoCo is not installed.

    A robot's install leaves the simulator out (``percept[sim]`` adds it). A command that will need
    it calls this first, so that the missing module is reported before kernels compile, devices open
    or child processes start, rather than deep inside one of them.
    """
    require("mujoco")
