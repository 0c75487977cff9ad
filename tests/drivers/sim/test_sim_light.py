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

ROOT = Path(__file__).resolve().parents[3]
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


def two_lamps(timeline: list[dict[str, Any]], camera: dict[str, Any] | None = None) -> Scene:
    data = {
        "name": "lamps",
        "robots": [
            {"name": "a", "profile": str(PROFILE), "joints": {"head_tilt": {"offset": -0.5}}}
        ],
        "timeline": timeline,
        "camera": camera or {},
        "lighting": {
            "ambient": [0.2, 0.2, 0.2],
            "lights": [
                {"diffuse": [0.25, 0.25, 0.25], "direction": [0.5, 0.0, -1.0]},
                {"diffuse": [0.25, 0.25, 0.25], "direction": [-0.5, 0.0, -1.0]},
            ],
        },
    }
    return build(Scene, data, ROOT / "config" / "scenes" / "test.toml")


def test_one_lamp_alone_changes_when_an_event_names_it() -> None:
    """Lamp 1 off at t = 1: the floor darkens, but less than when every lamp and the ambient
    light go off (the other lamp and the ambient light stay)."""
    s = two_lamps(
        [
            {"t": 1.0, "action": "lights", "lamp": 1, "scale": 0.0},
            {"t": 2.0, "action": "lights", "scale": 0.0},
        ]
    )
    with SimWorld(s, {"a": load_profile(PROFILE)}) as world:
        full, one_off, all_off = (brightness(world, t) for t in (0.5, 1.5, 2.5))
    assert all_off < 0.1 * full
    assert 0.3 * full < one_off < 0.95 * full


def test_a_lamp_that_is_not_there_is_a_scene_error() -> None:
    with pytest.raises(ConfigError, match="no lamp 2"):
        two_lamps([{"t": 1.0, "action": "lights", "lamp": 2, "scale": 0.5}])


def test_a_white_balance_step_changes_the_channels_apart() -> None:
    s = two_lamps([{"t": 1.0, "action": "white_balance", "gains": [1.2, 1.0, 0.8]}])
    with SimWorld(s, {"a": load_profile(PROFILE)}) as world:
        before = world.render("a", 0.5).astype(float)[100:].mean(axis=(0, 1))
        after = world.render("a", 1.5).astype(float)[100:].mean(axis=(0, 1))
    b, g, r = after / before
    assert r == pytest.approx(1.2, abs=0.03)
    assert g == pytest.approx(1.0, abs=0.02)
    assert b == pytest.approx(0.8, abs=0.03)


def test_jpeg_and_motion_blur_of_a_turning_head() -> None:
    """JPEG changes pixels a little; a head turning at 1 rad/s with a 30 ms shutter smears
    the image along its motion (fewer strong horizontal gradients), a still head does not."""
    from percept.drivers.sim.effects import motion_blur

    image = np.zeros((40, 40, 3), np.uint8)
    image[:, 20:] = 200
    smeared = motion_blur(image, (9.0, 0.0))
    assert 0 < smeared[20, 17, 0] < 200 and 0 < smeared[20, 23, 0] < 200
    assert (motion_blur(image, (0.4, 0.2)) == image).all()
    data = {
        "name": "blur",
        "robots": [
            {
                "name": "a",
                "profile": str(PROFILE),
                "joints": {
                    "head_tilt": {"offset": -0.5},
                    "head_pan": {"keyframes": [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]]},
                },
            }
        ],
        "camera": {"shutter": 0.03, "jpeg_quality": 70},
    }
    s = build(Scene, data, ROOT / "config" / "scenes" / "test.toml")
    with SimWorld(s, {"a": load_profile(PROFILE)}) as world:
        still, turning = world.render("a", 0.5), world.render("a", 1.5)
        clean = world.render("a", 0.5, effects=False)

    def sharpness(im: np.ndarray) -> float:
        gray = im.mean(axis=2)
        return float(np.abs(np.diff(gray, axis=1)).mean())

    assert 0 < np.abs(still.astype(int) - clean).mean() < 4  # JPEG: close, not equal
    assert sharpness(turning) < 0.7 * sharpness(still)
