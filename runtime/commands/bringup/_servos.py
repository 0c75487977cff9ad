"""Shared by the servo commands: a profile with servos on its bus."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from percept.config.loader import ConfigError

if TYPE_CHECKING:
    from percept.runtime.settings.profile import PlatformProfile


def load_servo_profile(path: str | Path) -> PlatformProfile:
    """The profile at ``path``, with at least one servo (each of a model its bus protocol has:
    :class:`~percept.runtime.settings.profile.PlatformProfile` checks that when it loads)."""
    from percept.runtime.settings.profile import load_profile

    profile = load_profile(path)
    if not profile.joints:
        raise ConfigError(path, "joints", "no servos configured")
    return profile
