"""The simulated world's light over time: ``lights`` and ``exposure`` events change what the
camera renders (real MuJoCo renders), and the events are checked when a scene is read."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from percept.config.loader import ConfigError, build
from percept.drivers.sim.light import Level
from percept.drivers.sim.scene import Scene
from percept.drivers.sim.world import SimWorld
from percept.runtime.settings.profile import load_profile

pytestmark = pytest.mark.timeout(120)

ROOT = Path(__file__).resolve().parents[2]
PROFILE = ROOT / "config" / "robots" / "robotis-op3.toml"


def scene(timeline: list[dict[str, Any]]) -> Scene:
    data = {
        "name": "light",
        "robots": [
            {"name": "a", "profile": str(PROFILE), "joints": {"head_tilt": {"offset": -0.5}}}
        ],
        "timeline": timeline,
        # dim enough that no pixel saturates, so that the image scales with the light
        "lighting": {"ambient": [0.3, 0.3, 0.3], "lights": [{"diffuse": [0.4, 0.4, 0.4]}]},
    }
    return build(Scene, data, ROOT / "config" / "scenes" / "test.toml")


def brightness(world: SimWorld, t: float, effects: bool = False) -> float:
    """Mean of the lower half of the image: the floor (the sky above is not lit by lamps)."""
    image = world.render("a", t, effects=effects)
    return float(image[image.shape[0] // 2 :].astype(np.float64).mean())


def test_lights_scale_the_rendered_brightness() -> None:
    """A switch to 50 % at t = 1, then a ramp back to 100 % over t = 2-4: the image's mean
    follows the scale (the floor is far from saturation)."""
    s = scene(
        [
            {"t": 1.0, "action": "lights", "scale": 0.5},
            {"t": 2.0, "action": "lights", "scale": 1.0, "duration": 2.0},
        ]
    )
    with SimWorld(s, {"a": load_profile(PROFILE)}) as world:
        full = brightness(world, 0.5)
        assert brightness(world, 1.5) / full == pytest.approx(0.5, abs=0.02)
        assert brightness(world, 3.0) / full == pytest.approx(0.75, abs=0.02)
        assert brightness(world, 5.0) / full == pytest.approx(1.0, abs=0.01)


def test_an_exposure_step_scales_the_delivered_image() -> None:
    s = scene([{"t": 1.0, "action": "exposure", "scale": 1.3}])
    with SimWorld(s, {"a": load_profile(PROFILE)}) as world:
        before, after = brightness(world, 0.5, True), brightness(world, 1.5, True)
        assert after / before == pytest.approx(1.3, abs=0.03)
        assert brightness(world, 1.5) == pytest.approx(before, abs=0.5)  # the scene is as lit


def test_a_later_event_starts_where_a_ramp_has_got_to() -> None:
    level = Level([(10.0, 0.5, 10.0), (15.0, 1.0, 0.0)])
    assert level.at(0.0) == 1.0
    assert level.at(12.5) == pytest.approx(0.875)
    assert level.at(15.0) == 1.0
    assert Level([(0.0, 0.2, 4.0), (2.0, 0.2, 2.0)]).at(3.0) == pytest.approx(0.4)


@pytest.mark.parametrize(
    ("event", "problem"),
    [
        ({"t": 1.0, "action": "lights"}, "needs a scale"),
        ({"t": 1.0, "action": "lights", "scale": 0.5, "object": 1}, "acts on no object"),
        ({"t": 1.0, "action": "remove"}, "needs an object"),
        ({"t": 1.0, "action": "exposure", "scale": 0.5, "path": [[0, 0]]}, "does not take path"),
    ],
)
def test_light_events_are_checked(event: dict[str, Any], problem: str) -> None:
    with pytest.raises(ConfigError, match=problem):
        scene([event])
