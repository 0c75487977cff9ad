"""The lag of the camera poses behind the images (:mod:`percept.perception.view.register`) and
the hue that tells another object from a face of a model's object in another shade."""

from __future__ import annotations

import math

import numpy as np
import pytest

from percept.perception.colour import hue, to_ycrcb
from percept.perception.tracking.anchors import SAME_HUE, _same_hue
from percept.perception.view.register import fit_lag

FX = 130.0  # grid pixels per radian


def _sweep(frames: int = 90) -> np.ndarray:
    """Motion per frame (pan, tilt; radians) of a head that sweeps left, then right."""
    pan = 0.03 * np.sign(np.sin(np.linspace(0.0, 2 * math.pi, frames, endpoint=False)))
    return np.column_stack([pan, np.zeros(frames)])


def test_the_lag_is_found_beside_a_constant_offset_and_outliers() -> None:
    moved = _sweep()
    rng = np.random.default_rng(3)
    turns = np.array([0.004, -0.002]) + 0.6 * moved + rng.normal(0.0, 0.5 / FX, moved.shape)
    turns[::15] += 0.05  # frames the correlation got wrong
    assert fit_lag(turns, moved, np.ones(len(moved), bool), FX) == pytest.approx(0.6, abs=0.05)


def test_no_lag_without_a_change_of_the_motion() -> None:
    # An even pan: a lag is a constant offset there, which the frames share.
    moved = np.tile([0.03, 0.0], (60, 1))
    turns = np.tile([0.012, 0.0], (60, 1))
    assert fit_lag(turns, moved, np.ones(60, bool), FX) == 0.0


def _histograms(bgr: tuple[int, int, int], bins: int = 16) -> np.ndarray:
    """The (3, bins) histograms of a patch of one colour."""
    ycc = to_ycrcb(np.full((1, 1, 3), bgr, np.uint8))[0, 0]
    h = np.zeros((3, bins))
    h[np.arange(3), ycc // (256 // bins)] = 1.0
    return h


def test_shades_of_a_colour_have_its_hue_and_other_colours_another() -> None:
    pink, dark_pink = _histograms((170, 90, 220)), _histograms((110, 58, 143))
    orange = _histograms((20, 120, 240))
    grey = _histograms((150, 150, 150))
    angles, chroma = hue(np.array([pink, dark_pink, orange]))
    # (16 bins of one colour each: the hue of the darker shade is rounded off more)
    assert abs(angles[0] - angles[1]) < SAME_HUE / 2
    assert abs(angles[0] - angles[2]) > 2 * SAME_HUE
    assert chroma.min() > 20
    same = _same_hue(np.array([dark_pink, orange, grey]), np.array([pink]))
    assert same[:, 0].tolist() == [True, False, True]  # grey: no hue to tell
