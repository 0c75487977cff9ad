"""Reading a marker's id from a dark quadrilateral, all candidates of an image at once.

cv2.aruco (5.0) reads a candidate's bits and then compares them with each marker of the
dictionary in turn: 3 ms per candidate for the 587 markers of 36h11, most of the search's time
on a cluttered image (its quad search takes 3 ms for the whole image). Here the bits of every
candidate are read at once (:func:`.quads_kernels.cell_levels`), by the
homography of its corners, as the mean grey level of the middle of each cell, split into black
and white by Otsu's threshold over its cells; the bits are compared with every marker in all four
rotations as 64-bit words (XOR and bit count).

A reading is accepted when its border is mostly black, its bits are within the dictionary's
correctable errors of a marker's, and every bit that disagrees is a doubtful one: a printed
marker misread by blur or noise has its wrong cells near the threshold, whereas a pattern that
is no marker (a black square of random bits) differs from the nearest marker in cells that are
clearly black or white. On ``bench/bench_markers.py``'s 240 pictures (without this test) the
wrong cells of the 1526 markers read lay within 0.33 of the contrast from the threshold (95 % of
those with a wrong cell within 0.26; 4 at 0.3 or more, which the test drops), those of the 7
random squares that came within 5 bits of a marker at 0.44 and more.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from percept.perception.landmarks.detection.quads_kernels import cell_levels

INSET = 0.25  # the part of a cell at each side not read: blur from the neighbours
READS = 2  # points read per cell and axis
DOUBT = 0.3  # fraction of the contrast: a wrong cell nearer the threshold is a doubtful one
BORDER_ERRORS = 0.35  # cv2.aruco's maxErroneousBitsInBorderRate: of markerSize squared
MIN_CONTRAST = 10.0  # grey levels between the darkest and brightest cell


@dataclass(frozen=True)
class Reading:
    """A candidate read as a marker: its index among the candidates, the marker's id, how many
    quarter turns its corners are rolled by to start at the marker's top-left, and how many of
    its bits were wrong."""

    candidate: int
    id: int
    rotation: int
    errors: int


class Codebook:
    """A cv2.aruco dictionary as 64-bit words (all four rotations), and the reading of
    candidates against it."""

    def __init__(self, dictionary: cv2.aruco.Dictionary) -> None:
        m = int(dictionary.markerSize)
        if m * m > 64:
            raise ValueError(f"markers of {m}x{m} bits do not fit a 64-bit word")
        self.size = m
        self.max_errors = int(dictionary.maxCorrectionBits)
        self._bit = np.uint64(1) << np.arange(m * m, dtype=np.uint64)
        bytes_list = dictionary.bytesList
        bits = np.stack(
            [
                cv2.aruco.Dictionary.getBitsFromByteList(bytes_list[i : i + 1], m)
                for i in range(len(bytes_list))
            ]
        )
        # every marker's four rotations at once (a loop over the 587 markers of AprilTag 36h11
        # and their rotations took 0.06 s of CPU at every start, twice: warm-up and daemon)
        rotations = [np.rot90(bits, r, axes=(1, 2)).reshape(len(bits), -1) for r in range(4)]
        self._words = np.stack([self._word(b) for b in rotations], axis=1)
        cells = m + 2  # with the black border
        self._within = INSET + (np.arange(READS) + 0.5) / READS * (1 - 2 * INSET)
        border = np.ones((cells, cells), bool)
        border[1:-1, 1:-1] = False
        self._border = border.ravel()

    def _word(self, bits: np.ndarray) -> np.ndarray:
        return (bits.astype(np.uint64) * self._bit).sum(axis=1)

    def read(self, gray: np.ndarray, quads: np.ndarray) -> list[Reading]:
        """The candidates ``quads`` (N, 4, 2) (corners clockwise in the image, in pixels) of
        ``gray`` that read as markers."""
        n, cells = len(quads), self.size + 2
        if n == 0:
            return []
        quads = np.ascontiguousarray(quads, dtype=float)
        levels = cell_levels(np.ascontiguousarray(gray), quads, cells, self._within)
        levels = levels.reshape(n, cells * cells)
        threshold, contrast = _otsu(levels)
        white = levels > threshold[:, None]
        inner = white.reshape(n, cells, cells)[:, 1:-1, 1:-1].reshape(n, -1)
        distances = np.bitwise_count(self._words[None] ^ self._word(inner)[:, None, None])
        best = distances.reshape(n, -1).argmin(axis=1)
        ids, rotations = np.divmod(best, 4)
        errors = distances.reshape(n, -1)[np.arange(n), best]
        # How far from the threshold the worst wrong bit lies, in parts of the contrast.
        shifts = np.arange(self.size**2, dtype=np.uint64)
        expected = ((self._words[ids, rotations][:, None] >> shifts) & np.uint64(1)).astype(bool)
        inner_levels = levels.reshape(n, cells, cells)[:, 1:-1, 1:-1].reshape(n, -1)
        away = np.abs(inner_levels - threshold[:, None]) / np.maximum(contrast, 1.0)[:, None]
        doubt = np.where(expected != inner, away, 0.0).max(axis=1)
        ok = (
            (white[:, self._border].sum(axis=1) <= int(self.size**2 * BORDER_ERRORS))
            & (errors <= self.max_errors)
            & (doubt < DOUBT)
            & (contrast > MIN_CONTRAST)
        )
        return [
            Reading(int(i), int(ids[i]), int(rotations[i]), int(errors[i]))
            for i in np.flatnonzero(ok)
        ]


def _otsu(levels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Otsu's threshold of each row of ``levels`` (N, K), and each row's contrast (range)."""
    n, k = levels.shape
    ordered = np.sort(levels, axis=1)
    below = np.arange(1, k)
    sums = np.cumsum(ordered, axis=1)[:, :-1]
    mean_low = sums / below
    mean_high = (ordered.sum(axis=1, keepdims=True) - sums) / (k - below)
    split = (below * (k - below) * (mean_low - mean_high) ** 2).argmax(axis=1)
    rows = np.arange(n)
    threshold = (ordered[rows, split] + ordered[rows, split + 1]) / 2
    return threshold, ordered[:, -1] - ordered[:, 0]
