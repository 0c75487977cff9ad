"""Scene files of the simulated world: found by name or path, loaded with exact errors, together
with the platform profiles of their robots."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from percept.config import find
from percept.config.loader import ConfigError, load
from percept.drivers.sim.scene import Scene, SceneError, SimRobot
from percept.runtime.settings.profile import PlatformProfile, load_profile

if TYPE_CHECKING:
    from percept.drivers.sim.world import SimWorld


def find_scene(name: str | Path) -> Path:
    """The scene file ``name``: a path to a file, or the name of a shipped scene."""
    return find("scenes", name)


def load_scene(path: str | Path) -> tuple[Scene, dict[str, PlatformProfile]]:
    """The scene in ``path`` and each of its robots' platform profile, by robot name."""
    scene = load(Scene, path)
    platforms = {r.name: load_profile(robot_profile(r)) for r in scene.robots}
    return scene, platforms


def robot_profile(robot: SimRobot) -> Path | str:
    """A scene robot's ``profile`` as :func:`~percept.config.find` takes it: the file, or, when it
    is a bare name that is no file beside the scene, the name of a shipped profile (``profile =
    "robotis-op3"``, as the scenario generator writes it)."""
    path = robot.profile
    if path.suffix or path.exists():
        return path
    return path.name


def open_world(name: str | Path) -> SimWorld:
    """The simulated world of scene ``name`` (see :func:`find_scene`), ready to render."""
    from percept.drivers.sim.world import SimWorld

    path = find_scene(name)
    scene, platforms = load_scene(path)
    try:
        return SimWorld(scene, platforms)
    except SceneError as err:
        raise ConfigError(path, err.key, err.problem) from None
