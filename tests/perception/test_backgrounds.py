"""The background chosen with the calibration (:mod:`percept.perception.backgrounds`): fixed
or lit per-pixel, or the moving head's view background around either, which tells a frame at
the still calibration's pose from the per-pixel model and one turned away from its view. What
each gives, to the bit, is in test_fingerprint.py."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.perception.backgrounds import FixedBackground, LitBackground, ViewBackground
from percept.perception.colour import to_ycrcb
from percept.perception.evaluation.cubes import head_pose, render
from percept.perception.evaluation.synthetic import SyntheticScene
from percept.perception.params import PerceptionParams
from percept.perception.pipeline import Perception

W, H = 64, 48
CAMERA = CameraModel.from_opening_angles(math.radians(60), math.radians(47), W, H)


def params(light: bool) -> PerceptionParams:
    base = PerceptionParams()
    return replace(
        base,
        background=replace(base.background, calibration_frames=4),
        light=replace(base.light, enabled=light),
    )


def test_a_still_camera_gets_the_fixed_or_the_lit_per_pixel_background() -> None:
    for light, kind in ((False, FixedBackground), (True, LitBackground)):
        perception = Perception(params(light), W, H)
        assert perception.subtraction is None
        perception.calibrate(SyntheticScene(W, H, [], seed=1).empty(4))
        assert type(perception.subtraction) is kind
        assert (perception.subtraction.status is None) is not light


def test_a_head_calibrated_still_is_told_per_frame_from_the_right_background() -> None:
    rng = np.random.default_rng(1)
    for light, still in ((False, FixedBackground), (True, LitBackground)):
        perception = Perception(params(light), W, H, CAMERA)
        frames = [render([], 0, CAMERA, head_pose(0.0), rng)[0] for _ in range(4)]
        perception.calibrate(frames, poses=[head_pose(0.0)] * 4)
        background = perception.subtraction
        assert isinstance(background, ViewBackground) and type(background.still) is still
        at_rest = render([], 0, CAMERA, head_pose(0.0), rng)[0]
        turned = render([], 0, CAMERA, head_pose(0.2), rng)[0]
        boxes = np.zeros((0, 4))
        seen = background.foreground(to_ycrcb(at_rest), head_pose(0.0), None, boxes, 0.0)
        assert seen.view is None and seen.upper is None and seen.unknown_fraction == 0.0
        seen = background.foreground(to_ycrcb(turned), head_pose(0.2), None, boxes, 0.1)
        assert seen.view is not None and seen.upper is not None
        assert seen.unknown_fraction > 0  # turned away from all that was calibrated
        assert not background.holding(seen)
