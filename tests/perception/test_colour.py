"""The colour models: the marginals' product and the joint chroma, counted by the compiled
kernels and read back as the features' mean colours."""

from __future__ import annotations

import numpy as np
import pytest

from percept.perception.colour import Coding, histogram_means, hue
from percept.perception.segmentation.labelling.regions import find_regions
from percept.perception.segmentation.split_kernels import classify

THRESHOLD = 2e-4
"""The colour split's default: just under a uniform model's 1 / 16^3."""


def pixels(*colours: tuple[int, int, int], each: int = 50) -> np.ndarray:
    """(k, 3) uint8 YCrCb pixels: ``each`` of every colour."""
    return np.repeat(np.array(colours, np.uint8), each, axis=0)


def test_histogram_means_on_the_0_255_scale() -> None:
    h = np.zeros((3, 8))
    h[0, 0], h[1, 7], h[2, 3:5] = 2.0, 1.0, 0.5  # need not be normalised
    assert histogram_means(h).tolist() == [16.0, 240.0, 128.0]
    assert histogram_means(np.full((3, 16), 1 / 16)) == pytest.approx([128.0] * 3)
    with pytest.raises(ValueError):
        histogram_means(np.zeros((3, 16)))


@pytest.mark.parametrize("joint", [False, True])
def test_histograms_sum_to_one_per_factor_and_give_the_mean_colour(joint) -> None:
    rng = np.random.default_rng(3)
    ycc = rng.integers(0, 256, (500, 3)).astype(np.uint8)
    coding = Coding(16, joint)
    h = coding.histograms(ycc)
    assert h.shape == coding.shape == ((2, 256) if joint else (3, 16))
    np.testing.assert_allclose(h.sum(axis=1), 1.0)
    bin_centres = (ycc // 16) * 16 + 8.0
    np.testing.assert_allclose(histogram_means(h), bin_centres.mean(axis=0))
    assert Coding.of_histograms(h) == coding


def test_both_models_of_the_same_pixels_have_the_same_mean_colour_and_hue() -> None:
    rng = np.random.default_rng(4)
    ycc = rng.integers(40, 220, (300, 3)).astype(np.uint8)
    apart, joint = Coding(8, False).histograms(ycc), Coding(8, True).histograms(ycc)
    np.testing.assert_allclose(histogram_means(apart), histogram_means(joint))
    np.testing.assert_allclose(hue(apart), hue(joint))


@pytest.mark.parametrize("shape", [(1, 16), (2, 200), (4, 16), (5, 2, 8)])
def test_histograms_of_no_colour_model_are_refused(shape) -> None:
    with pytest.raises(ValueError, match="no colour model"):
        Coding.of_histograms(np.zeros(shape))


def test_the_regions_count_the_joint_bins_of_their_pixels() -> None:
    mask = np.zeros((20, 30), np.uint8)
    mask[5:15, 5:25] = 1
    ycc = np.zeros((20, 30, 3), np.uint8)
    ycc[..., 0], ycc[..., 1], ycc[..., 2] = 100, 170, 90
    ycc[5:15, 15:25] = (100, 90, 170)
    regions = find_regions(mask, ycc, Coding(16, True), 5)
    (h,) = regions.histograms
    assert h.shape == (2, 256)
    assert h[0, 100 // 16] == 1.0
    expected = {(170 // 16) * 16 + 90 // 16: 0.5, (90 // 16) * 16 + 170 // 16: 0.5}
    assert {int(b): float(h[1, b]) for b in np.flatnonzero(h[1])} == expected
    assert set(regions.pixel_bins[:, 1].tolist()) == set(expected)


def classes(coding: Coding, model: np.ndarray, colours: np.ndarray) -> list[int]:
    """The colour split's class of each of the YCrCb ``colours`` (k, 3), one region of a row
    of pixels, with one ``model`` over it: 1 where the model explains a pixel, 0 where not."""
    k = len(colours)
    regions = find_regions(np.ones((1, k), np.uint8), colours.reshape(1, k, 3), coding, 1)
    box = np.array([[0.0, 0.0, k, 1.0]])
    got = classify(
        regions.boxes, regions.offsets, regions.pixel_bins, box, model[None], THRESHOLD, 0.5
    )
    return got.tolist()


def test_a_model_of_two_colours_explains_their_crossings_only_as_marginals() -> None:
    # A model learnt from two colours, (Cr low, Cb high) and (Cr high, Cb low), as an object's
    # lit and shaded faces of different tints; the pixel asked about has Cr high and Cb high:
    # a colour the model never saw, between those it did.
    seen = pixels((120, 100, 170), (120, 170, 100))
    crossing = pixels((120, 170, 170), each=1)
    for joint, claimed in ((False, 1), (True, 0)):
        coding = Coding(16, joint)
        model = coding.histograms(seen)
        assert classes(coding, model, crossing) == [claimed], coding
        assert classes(coding, model, seen[::50]) == [1, 1]  # both claim what they were made of
