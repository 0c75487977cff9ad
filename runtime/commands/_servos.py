"""Shared by the servo commands: the profile's servo models checked against its bus protocol."""

from __future__ import annotations

from pathlib import Path

from drivers.dynamixel.models import find_model
from runtime.config import ConfigError
from runtime.profile import PlatformProfile, load_profile


def load_servo_profile(path: str | Path) -> PlatformProfile:
    """The profile at ``path``, with at least one servo, each of a model its bus protocol has."""
    profile = load_profile(path)
    if not profile.joints:
        raise ConfigError(path, "joints", "no servos configured")
    for i, joint in enumerate(profile.joints):
        try:
            find_model(joint.model, profile.bus.protocol)
        except ValueError as err:
            raise ConfigError(path, f"joints[{i}].model", str(err)) from None
    return profile
