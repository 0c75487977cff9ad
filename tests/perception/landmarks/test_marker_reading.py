"""percept's own marker reading (landmarks.detection.decoding) and edge-fitted corners
(landmarks.detection.edges), on drawn markers whose cells and corners are known exactly."""

from __future__ import annotations

import cv2
import numpy as np

from percept.perception.evaluation.marker_photos import picture
from percept.perception.landmarks.detection.decoding import Codebook
from percept.perception.landmarks.detection.detector import load_dictionary
from percept.perception.landmarks.detection.edges import fit_edges
from tests.perception.landmarks.test_markers import VGA

CELL = 12  # pixels a cell in the drawn markers
MARGIN = 3 * CELL  # white around the black square


def _drawn(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A grey image of a marker of these cell levels (inner bits, 0-255) with its black
    border and a white margin, and its black square's corners (top-left first, clockwise)."""
    m = len(cells) + 2
    square = np.zeros((m, m), np.uint8)
    square[1:-1, 1:-1] = cells
    image = np.full((m * CELL + 2 * MARGIN,) * 2, 255, np.uint8)
    image[MARGIN:-MARGIN, MARGIN:-MARGIN] = np.kron(square, np.ones((CELL, CELL), np.uint8))
    lo, hi = MARGIN - 0.5, MARGIN + m * CELL - 0.5  # pixel centres at integers
    return image, np.array([[lo, lo], [hi, lo], [hi, hi], [lo, hi]])


def test_every_rotation_is_read_with_its_corners_rolled_to_the_printed_top_left() -> None:
    dictionary = load_dictionary("DICT_APRILTAG_36h11")
    codebook = Codebook(dictionary)
    bits = dictionary.getMarkerBits(42).astype(np.uint8) * 255
    image, corners = _drawn(bits)
    for turns in range(4):
        turned = np.ascontiguousarray(np.rot90(image, turns))
        # the image's corners, clockwise from its top-left, after turning it
        c = np.roll(corners, -turns, axis=0)
        (reading,) = codebook.read(turned, c[None])
        assert (reading.id, reading.errors) == (42, 0)
        top_left = np.roll(c, reading.rotation, axis=0)[0]
        # the printed top-left corner, where the unturned image has it
        n = image.shape[0] - 1
        expected = [(corners[0][0], corners[0][1]), (corners[0][1], n - corners[0][0])]
        expected += [(n - corners[0][0], n - corners[0][1]), (n - corners[0][1], corners[0][0])]
        assert np.allclose(top_left, expected[turns]), turns


def test_wrong_cells_near_the_threshold_are_corrected_clear_ones_are_not() -> None:
    dictionary = load_dictionary("DICT_APRILTAG_36h11")
    codebook = Codebook(dictionary)
    bits = dictionary.getMarkerBits(7).astype(np.uint8) * 255
    flipped = [(0, 1), (2, 3), (4, 4)]
    doubtful, wrong = bits.copy(), bits.copy()
    for r, c in flipped:
        doubtful[r, c] = 150 if bits[r, c] == 0 else 105  # just across the middle
        wrong[r, c] = 255 - bits[r, c]  # clearly the other colour
    image, corners = _drawn(doubtful)
    (reading,) = codebook.read(image, corners[None])
    assert (reading.id, reading.errors) == (7, 3)
    image, corners = _drawn(wrong)
    assert codebook.read(image, corners[None]) == []


def test_fitted_corners_reach_the_truth_from_a_pixel_off() -> None:
    rng = np.random.default_rng(4)
    errors_before, errors_after = [], []
    for _ in range(3):
        p = picture(rng, "clean", VGA, (25.0, 80.0))
        gray = cv2.cvtColor(p.image, cv2.COLOR_BGR2GRAY)
        truth = np.array([t.corners for t in p.tags if t.findable])
        start = truth + rng.uniform(-1.0, 1.0, truth.shape)
        fitted = fit_edges(gray, start, 8)
        errors_before.extend(np.linalg.norm(start - truth, axis=2).ravel())
        errors_after.extend(np.linalg.norm(fitted - truth, axis=2).ravel())
    assert np.median(errors_before) > 0.5
    assert np.median(errors_after) < 0.15 and np.percentile(errors_after, 90) < 0.4
