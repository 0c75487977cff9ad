"""Marker detection with cv2.aruco, optionally after the chapter's global threshold."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

_REFINEMENT = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
}


class LandmarkError(ValueError):
    """A marker dictionary or detector setting that cannot be used."""


@dataclass(frozen=True)
class Marker:
    """A detected marker: its id and its corners (4, 2) in pixels, in OpenCV's order
    (top-left, top-right, bottom-right, bottom-left of the marker as printed)."""

    id: int
    corners: np.ndarray


def predefined_dictionaries() -> list[str]:
    """The names of cv2.aruco's predefined dictionaries."""
    return sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))


def load_dictionary(name: str = "DICT_APRILTAG_36h11", file: Path | None = None):
    """A cv2.aruco dictionary: predefined by ``name``, or read from an OpenCV YAML ``file``
    (``nmarkers``, ``markersize``, ``marker_<i>`` bit strings)."""
    if file is not None:
        fs = cv2.FileStorage(str(file), cv2.FILE_STORAGE_READ)
        dictionary = cv2.aruco.Dictionary()
        ok = fs.isOpened() and dictionary.readDictionary(fs.root())
        fs.release()
        if not ok:
            raise LandmarkError(f"{file}: not an OpenCV marker dictionary")
        return dictionary
    if name not in predefined_dictionaries():
        known = ", ".join(predefined_dictionaries())
        raise LandmarkError(f"unknown marker dictionary {name!r}; known: {known}")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def otsu_binary(gray: np.ndarray) -> np.ndarray:
    """The chapter's preprocessing: one global threshold derived from the luminance histogram
    (Otsu's method), giving a black and white image."""
    _, binary = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    return binary


class MarkerDetector:
    """Finds markers of one dictionary in images (BGR or grey)."""

    def __init__(
        self,
        dictionary: str = "DICT_APRILTAG_36h11",
        dictionary_file: Path | None = None,
        threshold: str = "adaptive",
        corner_refinement: str = "subpix",
    ) -> None:
        if threshold not in ("adaptive", "otsu"):
            raise LandmarkError(f"threshold must be adaptive or otsu, got {threshold!r}")
        if corner_refinement not in _REFINEMENT:
            raise LandmarkError(f"unknown corner refinement {corner_refinement!r}")
        markers = load_dictionary(dictionary, dictionary_file)
        self._apriltag = corner_refinement == "apriltag"
        params = cv2.aruco.DetectorParameters()
        # With apriltag, cv2.aruco runs AprilTag's whole quad search on the image (40 ms at
        # 640x480); ArUco's search without refinement (5 ms) finds the same markers, and the
        # AprilTag refiner then runs only on a window around each of them. For the same markers,
        # ArUco keeps candidates nearer each other (a box's two faces, seen round its edge) and
        # reads bits finer (markers seen at a slant): with its defaults it missed 10 of the 522
        # markers AprilTag finds in 240 images of bench/landmarks_sim.py, and 2 of 256 at
        # 640x480; with these none, nor any on OpenCV's tutorial photos.
        params.cornerRefinementMethod = _REFINEMENT["none" if self._apriltag else corner_refinement]
        if self._apriltag:
            params.minMarkerDistanceRate = 0.05
            params.perspectiveRemovePixelPerCell = 8
        self._detector = cv2.aruco.ArucoDetector(markers, params)
        refiner = cv2.aruco.DetectorParameters()
        refiner.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
        self._refiner = cv2.aruco.ArucoDetector(markers, refiner)
        self._otsu = threshold == "otsu"

    @classmethod
    def from_settings(cls, settings) -> MarkerDetector:
        """From :class:`percept.perception.landmarks.settings.LandmarkSettings`."""
        return cls(
            settings.dictionary,
            settings.dictionary_file,
            settings.threshold,
            settings.corner_refinement,
        )

    def detect(self, image: np.ndarray) -> list[Marker]:
        """The markers in ``image``, sorted by id."""
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if self._otsu:
            gray = otsu_binary(gray)
        corners, ids, _rejected = self._detector.detectMarkers(gray)
        if ids is None:
            return []
        found = [
            Marker(int(i), np.asarray(c, dtype=float).reshape(4, 2))
            for i, c in zip(ids.ravel(), corners, strict=True)
        ]
        if self._apriltag:
            unique = {m.id: m for m in found}  # close candidates can repeat a marker
            refined = (self._refine(gray, m) for m in unique.values())
            found = [m for m in refined if m is not None]
        return sorted(found, key=lambda m: m.id)

    def _refine(self, gray: np.ndarray, marker: Marker) -> Marker | None:
        """``marker`` with AprilTag's corners from a window around it (None if AprilTag does
        not find it there)."""
        lo, hi = marker.corners.min(axis=0), marker.corners.max(axis=0)
        # Half the marker's size around it: AprilTag lost 31 of those 522 in windows of a
        # quarter (its quads need the marker's surroundings), none in these.
        margin = 0.5 * float((hi - lo).max()) + 4
        # AprilTag thresholds in 4x4 pixel tiles: a window starting on the image's tile grid
        # gives exactly the corners of a search over the whole image.
        x0, y0 = (max(int(v - margin) // 4 * 4, 0) for v in lo)
        x1, y1 = (int(v + margin) + 1 for v in hi)
        corners, ids, _rejected = self._refiner.detectMarkers(gray[y0:y1, x0:x1])
        if ids is None or marker.id not in ids:
            return None
        c = np.asarray(corners[ids.ravel().tolist().index(marker.id)], dtype=float).reshape(4, 2)
        # The AprilTag refiner puts pixel centres at (0.5, 0.5), OpenCV at (0, 0): its corners
        # come out half a pixel right and down (measured on rendered markers: +0.46, +0.42).
        return Marker(marker.id, c + np.array([x0, y0]) - 0.5)
