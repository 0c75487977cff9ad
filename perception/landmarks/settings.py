"""Typed settings of marker landmarks and boxes (the ``[landmarks]`` table of an experiment).

Every robot of an experiment shares these: the same box ids for the same markers is what lets
two robots compare box poses (SPEC §4.6).

A box's frame has its origin on the ground at the centre of the box's footprint, x towards its
``front`` face, y towards its ``left`` face, z up. A marker sits upright on one of the four side
faces: its side length is that of the black square (the whole marker as
``cv2.aruco.generateImageMarker`` draws it, without any white margin around it), ``offset`` moves
its centre from the face's centre (right and up, as seen by someone looking at the face) and
``roll`` turns it counter-clockwise in the face's plane, as seen from outside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from percept.config.extras import installed, missing
from percept.config.loader import FieldError

Face = Literal["front", "back", "left", "right"]

#: cv2.aruco's AprilTag dictionaries and the AprilTag C library's names of the same families
#: (the dictionaries ``detector = "apriltag"`` reads).
APRILTAG_FAMILIES = {
    "DICT_APRILTAG_16h5": "tag16h5",
    "DICT_APRILTAG_25h9": "tag25h9",
    "DICT_APRILTAG_36h11": "tag36h11",
}


@dataclass(frozen=True)
class MarkerSettings:
    """One marker on a box: its id in the dictionary, size and place on the box."""

    id: int = field(metadata={"min": 0, "max": 100000, "doc": "marker id in the dictionary"})
    side: float = field(
        metadata={"min": 0.005, "max": 2.0, "doc": "side of the black square, metres"}
    )
    face: Face = field(default="front", metadata={"doc": "box face the marker is on"})
    offset: tuple[float, float] = field(
        default=(0.0, 0.0),
        metadata={"min": -2.0, "max": 2.0, "doc": "centre from the face centre: right, up (m)"},
    )
    roll: float = field(
        default=0.0,
        metadata={"min": -math.pi, "max": math.pi, "doc": "turn in the face plane, radians"},
    )


@dataclass(frozen=True)
class BoxSettings:
    """A carton box used as a landmark: its id (shared by all robots), size and markers."""

    id: int = field(metadata={"min": 0, "max": 100000, "doc": "box id"})
    size: tuple[float, float, float] = field(
        metadata={"min": 0.01, "max": 5.0, "doc": "length (front-back), width, height, metres"}
    )
    markers: tuple[MarkerSettings, ...] = field(metadata={"doc": "markers on the box"})

    def __post_init__(self) -> None:
        if not self.markers:
            raise ValueError(f"box {self.id} needs at least one marker")
        length, width, height = self.size
        for m in self.markers:
            face_width = width if m.face in ("front", "back") else length
            right, up = m.offset
            half = m.side / 2
            if abs(right) + half > face_width / 2 + 1e-9 or abs(up) + half > height / 2 + 1e-9:
                raise ValueError(
                    f"marker {m.id} does not fit on the {m.face} face of box {self.id}"
                )


@dataclass(frozen=True)
class LandmarkSettings:
    """Marker detection, marker and box pose estimation, and the boxes of the experiment."""

    dictionary: str = field(
        default="DICT_APRILTAG_36h11",
        metadata={"doc": "cv2.aruco predefined dictionary name"},
    )
    dictionary_file: Path | None = field(
        default=None,
        metadata={"doc": "custom dictionary (OpenCV YAML: nmarkers, markersize, marker_i)"},
    )
    threshold: Literal["adaptive", "otsu"] = field(
        default="adaptive",
        metadata={
            "doc": "adaptive: cv2.aruco's own thresholding; otsu: the chapter's global threshold "
            "from the luminance histogram, applied before detection"
        },
    )
    detector: Literal["percept", "aruco", "apriltag"] = field(
        default="percept",
        metadata={
            "doc": "marker search: percept = cv2.aruco's quads, read by percept with corners "
            "fitted to the edges; aruco = cv2.aruco's with corner_refinement; apriltag = the "
            "AprilTag C library (pupil-apriltags; AprilTag dictionaries only)"
        },
    )
    corner_refinement: Literal["none", "subpix", "contour", "apriltag", "edges"] = field(
        default="edges",
        metadata={
            "doc": "corner refinement (edges: lines fitted to the edges; apriltag: AprilTag's "
            "corners in a window around each marker; none: the contour's integer corners; "
            "contour: detector aruco only; bench/bench_markers.py compares them)"
        },
    )
    decimation: int = field(
        default=2,
        metadata={"min": 1, "max": 4, "doc": "detector apriltag: quad search on 1/n the pixels"},
    )
    follow: int = field(
        default=0,
        metadata={
            "min": 0,
            "max": 1000,
            "doc": "searches between two full searches that only follow the markers found "
            "before, in windows predicted from the camera's motion (0: every search is full)",
        },
    )
    same_box: float = field(
        default=0.05,
        metadata={
            "min": 0.0,
            "max": 10.0,
            "doc": "metres: two sightings of one marker id in an image whose box poses differ "
            "more (or by more than 10 degrees) are an ambiguity, and neither is used",
        },
    )
    refine: Literal["lm", "vvs", "none"] = field(
        default="lm", metadata={"doc": "marker pose refinement after IPPE_SQUARE"}
    )
    box_fit: Literal["ground", "average"] = field(
        default="ground",
        metadata={
            "doc": "combine a box's markers in one image: ground = fit (x, y, theta) of the box "
            "standing on the ground to all their corners; average = the chapter's mean of the "
            "per-marker box poses"
        },
    )
    every: int = field(
        default=1, metadata={"min": 1, "max": 1000, "doc": "detect markers on every k-th frame"}
    )
    window: int = field(
        default=5, metadata={"min": 1, "max": 1000, "doc": "box poses averaged over n images"}
    )
    forget_after: float = field(
        default=5.0,
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "seconds a box is kept after it was last seen",
        },
    )
    max_tilt: float = field(
        default=0.5,
        metadata={
            "min": 0.0,
            "max": math.pi / 2,
            "doc": "radians a marker's normal may tilt from horizontal (markers sit on "
            "vertical faces); resolves the planar pose ambiguity",
        },
    )
    max_reprojection: float = field(
        default=3.0,
        metadata={
            "min": 0.0,
            "max": 10000.0,
            "doc": "pixels: drop marker poses that reproject worse (RMS)",
        },
    )
    boxes: tuple[BoxSettings, ...] = field(default=(), metadata={"doc": "landmark boxes"})

    def __post_init__(self) -> None:
        if self.dictionary_file is None:
            import cv2  # only here: a dictionary name is checked when the file loads

            if not self.dictionary.startswith("DICT_") or not hasattr(cv2.aruco, self.dictionary):
                raise ValueError(
                    f"unknown marker dictionary {self.dictionary!r} (cv2.aruco's DICT_* names, "
                    "e.g. DICT_APRILTAG_36h11, or give dictionary_file)"
                )
        elif not self.dictionary_file.is_file():
            raise ValueError(f"dictionary_file {self.dictionary_file} not found")
        if self.detector == "apriltag" and not installed("pupil_apriltags"):
            raise FieldError("detector", f"apriltag {missing('pupil_apriltags')}")
        if self.detector == "apriltag" and (
            self.dictionary_file is not None or self.dictionary not in APRILTAG_FAMILIES
        ):
            raise ValueError(
                f"detector apriltag reads only {', '.join(APRILTAG_FAMILIES)} (no dictionary_file)"
            )
        if self.detector == "percept" and self.corner_refinement == "contour":
            raise ValueError("corner_refinement contour needs detector aruco (its contours)")
        if self.detector == "apriltag" and self.follow:
            # pupil-apriltags corrupted the heap when run on many small windows (README).
            raise ValueError("detector apriltag searches whole images only: set follow = 0")
        box_ids = [b.id for b in self.boxes]
        marker_ids = [m.id for b in self.boxes for m in b.markers]
        for what, ids in (("box id", box_ids), ("marker id", marker_ids)):
            dupes = sorted({i for i in ids if ids.count(i) > 1})
            if dupes:
                raise ValueError(f"duplicate {what}: {', '.join(map(str, dupes))}")
