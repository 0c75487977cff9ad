"""Marker detection: percept's (cv2.aruco's quad search, percept's reading and edge-fitted
corners), cv2.aruco's or the AprilTag C library's, optionally after the chapter's global
threshold; every marker found is kept, copies of an id included."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from percept.perception.landmarks.detection.decoding import Codebook
from percept.perception.landmarks.detection.edges import fit_edges
from percept.perception.landmarks.detection.noise_kernels import noise_sigma
from percept.perception.landmarks.detection.quads_kernels import repeats
from percept.perception.landmarks.settings import APRILTAG_FAMILIES

_REFINEMENT = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
    "edges": cv2.aruco.CORNER_REFINE_NONE,  # then percept's lines fitted to the edges
}
DETECTORS = ("percept", "aruco", "apriltag")
REFINE_SCALES = (1, 2, 3)  # AprilTag's search in a window, then in it enlarged
SMALL = 60  # pixels: markers smaller than this are looked for in enlarged windows too
GRID = 8  # pixels: windows start on this grid (AprilTag's 4 px tiles, at decimation 2 too)
NOISE_MARGIN = 2.5  # cv2.aruco's adaptive threshold constant: at least this many noise sigmas
NOISE_ROWS = 8  # the noise is estimated on every this many rows
ROLLED = np.array([[0, 1, 2, 3], [3, 0, 1, 2], [2, 3, 0, 1], [1, 2, 3, 0]])  # np.roll's order


class LandmarkError(ValueError):
    """A marker dictionary or detector setting that cannot be used."""


@dataclass(frozen=True)
class Marker:
    """A detected marker: its id and its corners (4, 2) in pixels, in cv2.aruco's order
    (top-left, top-right, bottom-right, bottom-left of the marker as printed, i.e. clockwise in
    the image when the marker faces the camera) and OpenCV's pixel convention (the centre of
    the top-left pixel at (0, 0)), whichever detector found it."""

    id: int
    corners: np.ndarray


def reading_order(marker: Marker) -> tuple[int, float, float]:
    """The order markers are reported in: by id, copies of an id top to bottom."""
    return marker.id, float(marker.corners[:, 1].min()), float(marker.corners[:, 0].min())


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
    """Finds markers of one dictionary in images (BGR or grey), with one of three searches:

    - ``percept``: cv2.aruco's quad search (its candidates, not its reading of them), every
      candidate's corners fitted to its edges (:func:`.edges.fit_edges`) and read against the
      dictionary at once (:class:`.decoding.Codebook`); the markers' corners as
      ``corner_refinement`` says (``edges``, ``none``, ``subpix`` or ``apriltag``, not
      ``contour``, which needs cv2.aruco's contours);
    - ``aruco``: cv2.aruco's search with a corner refinement (``none``, ``subpix``,
      ``contour``, ``apriltag``: AprilTag's corners from a window around each marker found, or
      ``edges``: lines fitted to the edges as ``percept`` does);
    - ``apriltag``: the AprilTag C library (``pupil-apriltags``) on the whole image, its input
      decimated by ``decimation`` for the quad search (corners are fitted at full resolution);
      AprilTag dictionaries only.

    Whatever the search, corners come in cv2.aruco's order and pixel convention (see
    :class:`Marker`), and a marker seen twice in an image is reported twice.
    """

    def __init__(
        self,
        dictionary: str = "DICT_APRILTAG_36h11",
        dictionary_file: Path | None = None,
        threshold: str = "adaptive",
        corner_refinement: str = "edges",
        detector: str = "percept",
        decimation: int = 2,
    ) -> None:
        if threshold not in ("adaptive", "otsu"):
            raise LandmarkError(f"threshold must be adaptive or otsu, got {threshold!r}")
        if corner_refinement not in _REFINEMENT:
            raise LandmarkError(f"unknown corner refinement {corner_refinement!r}")
        if detector not in DETECTORS:
            raise LandmarkError(f"detector must be one of {', '.join(DETECTORS)}, got {detector!r}")
        markers = load_dictionary(dictionary, dictionary_file)
        self._otsu = threshold == "otsu"
        self._apriltag_library = None
        if detector == "apriltag":
            family = APRILTAG_FAMILIES.get(dictionary)
            if dictionary_file is not None or family is None:
                known = ", ".join(APRILTAG_FAMILIES)
                raise LandmarkError(f"detector apriltag reads only {known}, not {dictionary!r}")
            from percept.perception.landmarks.detection.apriltag_library import AprilTagLibrary

            self._apriltag_library = AprilTagLibrary(
                families=family, nthreads=1, quad_decimate=float(decimation)
            )
            return
        self._apriltag = corner_refinement == "apriltag"
        self._refinement = corner_refinement
        self._cells = markers.markerSize + 2  # with the black border
        self._codebook = None
        params = cv2.aruco.DetectorParameters()
        # With apriltag, cv2.aruco runs AprilTag's whole quad search on the image (40 ms at
        # 640x480); ArUco's search without refinement (5 ms) finds the same markers, and the
        # AprilTag refiner then runs only on a window around each of them. For the same markers,
        # ArUco keeps candidates nearer each other (a box's two faces, seen round its edge) and
        # reads bits finer (markers seen at a slant): with its defaults it missed 10 of the 522
        # markers AprilTag finds in 240 images of bench/landmarks_sim.py, and 2 of 256 at
        # 640x480; with these none, nor any on OpenCV's tutorial photos. ArUco's own corners
        # are refined sub-pixel first: they stay where AprilTag's quad search in the window
        # fails.
        params.cornerRefinementMethod = _REFINEMENT[
            "subpix" if self._apriltag else corner_refinement
        ]
        if self._apriltag:
            params.minMarkerDistanceRate = 0.05
            params.perspectiveRemovePixelPerCell = 8
        if detector == "percept":
            if corner_refinement == "contour":
                raise LandmarkError("corner refinement contour needs detector aruco")
            # cv2.aruco only finds the candidates: it reads them against a dictionary of one
            # marker (its reading costs 3 ms a candidate against 36h11's 587), lets every
            # candidate through to that reading, and keeps candidates near each other apart
            # (all come back, as found or rejected).
            self._codebook = Codebook(markers)
            params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
            params.minMarkerDistanceRate = 0.0
            params.maxErroneousBitsInBorderRate = 1.0
            params.perspectiveRemovePixelPerCell = 1  # its reading is not used: the least
            params.perspectiveRemoveIgnoredMarginPerCell = 0.0
            # and no Otsu threshold per candidate: each reads as all black or all white (0.3 ms
            # of the 3.6 ms cv2.aruco takes on a frame of bench/bench_markers.py)
            params.minOtsuStdDev = 255.0
            markers = cv2.aruco.Dictionary(markers.bytesList[:1], markers.markerSize, 0)
        self._params = params
        self._perimeter = (params.minMarkerPerimeterRate, params.maxMarkerPerimeterRate)
        self._constant = params.adaptiveThreshConstant
        self._detector = cv2.aruco.ArucoDetector(markers, params)
        refiner = cv2.aruco.DetectorParameters()
        refiner.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
        self._refiner = cv2.aruco.ArucoDetector(markers, refiner)

    @classmethod
    def from_settings(cls, settings) -> MarkerDetector:
        """From :class:`percept.perception.landmarks.settings.LandmarkSettings`."""
        return cls(
            settings.dictionary,
            settings.dictionary_file,
            settings.threshold,
            settings.corner_refinement,
            settings.detector,
            settings.decimation,
        )

    def prepare(self, image: np.ndarray) -> np.ndarray:
        """The grey (or, with ``otsu``, black and white) image the search reads."""
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        return otsu_binary(gray) if self._otsu else gray

    def detect(self, image: np.ndarray) -> list[Marker]:
        """The markers in ``image``, sorted by id (then top to bottom)."""
        return self.detect_prepared(self.prepare(image))

    def detect_prepared(
        self, gray: np.ndarray, window: tuple[int, int, int, int] | None = None
    ) -> list[Marker]:
        """The markers in a :meth:`prepare` d image, or only in its ``window`` ``(x0, y0, x1,
        y1)`` (pixels; its start is moved down onto the grid of :data:`GRID` pixels, so a
        window gives the corners a search of the whole image gives)."""
        x0 = y0 = 0
        longest = max(gray.shape)
        if window is not None:
            x0, y0 = (max(int(v), 0) // GRID * GRID for v in window[:2])
            gray = gray[y0 : max(int(window[3]), y0), x0 : max(int(window[2]), x0)]
        if min(gray.shape) < 8:
            return []
        found = self._search(gray, longest)
        shift = np.array([x0, y0], dtype=float)
        return sorted((Marker(m.id, m.corners + shift) for m in found), key=reading_order)

    def _search(self, gray: np.ndarray, longest: int) -> list[Marker]:
        """The markers in ``gray``, a window of an image whose longer side is ``longest``."""
        if self._apriltag_library is not None:
            # The library's corners wrap the other way round from cv2.aruco's, starting at
            # cv2.aruco's third, and its pixel centres are at (0.5, 0.5) (measured against
            # the exact corners of perception.evaluation.marker_photos: +0.50, +0.50).
            return [
                Marker(int(d.tag_id), np.roll(np.asarray(d.corners, float)[::-1], 2, axis=0) - 0.5)
                for d in self._apriltag_library.detect(np.ascontiguousarray(gray))
            ]
        # ArUco bounds a marker's perimeter relative to the image's size: in a window, relative
        # to the whole image's, else it decodes every speck of a small window (4 ms a window).
        scale = longest / max(gray.shape)
        self._params.minMarkerPerimeterRate = self._perimeter[0] * scale
        self._params.maxMarkerPerimeterRate = self._perimeter[1] * scale
        if self._codebook is not None:
            # Sensor noise of a few grey levels turns each threshold window's black and white
            # image into a field of specks (16 000 to 22 000 contours a window on
            # bench/bench_markers.py's noise pictures, cv2.aruco's search 9 ms instead of 3):
            # a threshold constant of at least 2.5 times the noise keeps most of them out (twice
            # left some 6 000 a window, the noise pictures 1.5 times a clean one's time and the
            # slowest tenth of all; 2.5 times finds the same tags, 3 times lost one of 12-20 px).
            noise = noise_sigma(np.ascontiguousarray(gray), NOISE_ROWS)
            self._params.adaptiveThreshConstant = max(self._constant, NOISE_MARGIN * noise)
        self._detector.setDetectorParameters(self._params)
        corners, ids, rejected = self._detector.detectMarkers(gray)
        if self._codebook is not None:
            found = self._read(gray, list(corners) + list(rejected))
        elif ids is None:
            return []
        else:
            found = _distinct(
                [
                    Marker(int(i), np.asarray(c, dtype=float).reshape(4, 2))
                    for i, c in zip(ids.ravel(), corners, strict=True)
                ]
            )
            if self._refinement == "edges" and found:
                fitted = fit_edges(gray, np.array([m.corners for m in found]), self._cells)
                found = [Marker(m.id, c) for m, c in zip(found, fitted, strict=True)]
        if self._apriltag:
            # A refinement moves corners; it never loses a marker the search found.
            # AprilTag's quad search misses small markers: of 113 of 12-20 px found by ArUco
            # in perception.evaluation.marker_photos' pictures it found 28 in their windows, 88 in
            # the windows enlarged twice, 105 three times. Where it finds none, ArUco's corners
            # stay.
            found = [
                next((r for s in _scales(m) if (r := self._refine(gray, m, s))), m) for m in found
            ]
        return found

    def _read(self, gray: np.ndarray, candidates: list[np.ndarray]) -> list[Marker]:
        """The markers among cv2.aruco's ``candidates`` (corners clockwise in the image), read
        once their corners are fitted to their edges (read at the contour's integer corners,
        88.9 % of the tags of 12-20 px in bench/bench_markers.py's pictures are found, 93.9 %
        so); their corners as the refinement says:
        ``edges`` fitted again (which moves them by hundredths of a pixel), ``none`` the
        contour's, ``subpix`` the contour's refined by ``cv2.cornerSubPix``."""
        assert self._codebook is not None
        if not candidates:
            return []
        found = _separate(np.concatenate(candidates, dtype=float).reshape(-1, 4, 2))
        fitted = fit_edges(gray, found, self._cells, passes=1)
        readings = sorted(self._codebook.read(gray, fitted), key=lambda r: r.errors)
        read = [(r, Marker(r.id, fitted[r.candidate, ROLLED[r.rotation]])) for r in readings]
        kept = {id(m) for m in _distinct([m for _, m in read])}
        read = [(r, m) for r, m in read if id(m) in kept]
        markers = [m for _, m in read]
        if not markers:
            return []
        if self._refinement == "edges":
            corners = fit_edges(gray, np.array([m.corners for m in markers]), self._cells, 1)
        elif self._refinement in ("none", "subpix"):
            corners = np.array([found[r.candidate, ROLLED[r.rotation]] for r, _ in read])
            if self._refinement == "subpix":
                corners = _subpix(gray, corners, self._params, self._cells)
        else:
            return markers
        return [Marker(m.id, c) for m, c in zip(markers, corners, strict=True)]

    def _refine(self, gray: np.ndarray, marker: Marker, scale: int = 1) -> Marker | None:
        """``marker`` with AprilTag's corners from a window around it, enlarged ``scale``
        times (None if AprilTag does not find it there)."""
        lo, hi = marker.corners.min(axis=0), marker.corners.max(axis=0)
        # Half the marker's size around it: AprilTag lost 31 of those 522 in windows of a
        # quarter (its quads need the marker's surroundings), none in these.
        margin = 0.5 * float((hi - lo).max()) + 4
        # AprilTag thresholds in 4x4 pixel tiles: a window starting on the image's tile grid
        # gives exactly the corners of a search over the whole image.
        x0, y0 = (max(int(v - margin) // 4 * 4, 0) for v in lo)
        x1, y1 = (int(v + margin) + 1 for v in hi)
        patch = gray[y0:y1, x0:x1]
        if scale > 1:
            patch = cv2.resize(patch, None, fx=scale, fy=scale, interpolation=cv2.INTER_LINEAR)
        corners, ids, _rejected = self._refiner.detectMarkers(patch)
        if ids is None:
            return None
        # The AprilTag refiner puts pixel centres at (0.5, 0.5), OpenCV at (0, 0): its corners
        # come out half a pixel right and down (measured on rendered markers: +0.46, +0.42).
        shift = np.array([x0, y0], dtype=float) - 0.5
        options = [
            np.asarray(c, dtype=float).reshape(4, 2) / scale + shift
            for i, c in zip(ids.ravel(), corners, strict=True)
            if i == marker.id
        ]
        if not options:
            return None
        # The window may hold another copy of the id: the one nearest the marker is it.
        best = min(options, key=lambda c: float(np.abs(c - marker.corners).max()))
        if np.abs(best - marker.corners).max() > 0.25 * float((hi - lo).max()) + 2:
            return None  # another marker of this id, not this one
        return Marker(marker.id, best)


def _scales(marker: Marker) -> tuple[int, ...]:
    """The enlargements of a marker's window to try AprilTag's quad search in: only small
    markers' (below 60 px) are enlarged: a large window enlarged costs tens of milliseconds."""
    small = float(np.ptp(marker.corners, axis=0).max()) < SMALL
    return REFINE_SCALES if small else REFINE_SCALES[:1]


def _distinct(markers: list[Marker]) -> list[Marker]:
    """``markers`` without repeats of one marker (two candidates of the same id whose centres
    are closer than a quarter of its size: the outer and inner outline of one black square);
    copies of an id elsewhere in the image stay."""
    if not markers:
        return []
    corners = np.array([m.corners for m in markers])
    sizes = np.ptp(corners, axis=1).max(axis=1)
    centres = corners.mean(axis=1)
    near = np.linalg.norm(centres[:, None] - centres[None], axis=2) < 0.25 * sizes[:, None]
    kept: list[int] = []
    for i, m in enumerate(markers):
        if not any(markers[k].id == m.id and near[i, k] for k in kept):
            kept.append(i)
    return [markers[i] for i in kept]


def _separate(quads: np.ndarray) -> np.ndarray:
    """``quads`` (N, 4, 2) without repeats: cv2.aruco finds most quads once per threshold
    window, within a pixel of each other; the first of each is kept."""
    return quads[~repeats(quads)]


def _subpix(
    gray: np.ndarray, corners: np.ndarray, params: cv2.aruco.DetectorParameters, cells: int
) -> np.ndarray:
    """Corners (N, 4, 2) refined by ``cv2.cornerSubPix`` as cv2.aruco's ``subpix`` does: a
    window of ``relativeCornerRefinmentWinSize`` of a cell, at most ``cornerRefinementWinSize``."""
    out = []
    for c in corners:
        cell = float(np.linalg.norm(c - np.roll(c, -1, axis=0), axis=1).mean()) / cells
        size = min(
            max(1, round(params.relativeCornerRefinmentWinSize * cell)),
            params.cornerRefinementWinSize,
        )
        criteria = (
            cv2.TERM_CRITERIA_MAX_ITER | cv2.TERM_CRITERIA_EPS,
            params.cornerRefinementMaxIterations,
            params.cornerRefinementMinAccuracy,
        )
        points = c.astype(np.float32).reshape(-1, 1, 2)
        out.append(cv2.cornerSubPix(gray, points, (size, size), (-1, -1), criteria).reshape(4, 2))
    return np.array(out, dtype=float)
