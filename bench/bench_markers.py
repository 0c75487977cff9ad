"""Marker detectors on realistic pictures of 36h11 tags: recall, corner error, false positives,
time (issue 13).

The pictures are :func:`percept.perception.evaluation.marker_photos.picture_set` (tags with a white
border on box faces and cards, tilted up to 60°, 10-120 px, each picture with one of blur, motion
blur, noise, JPEG 50-70, uneven light, a highlight, occlusion or copies of an id, at 640x480 and
800x600, exact corners), plus OpenCV's tutorial photos (``../shared/data/opencv-aruco-tutorial``,
corners from OpenCV's own test, to 1 px). Detectors:

- ``percept``: percept's default detector: cv2.aruco's quad search, percept's reading of the
  quads (``percept.perception.landmarks.detection.decoding``) and corners fitted to the edges
  (``percept.perception.landmarks.detection.edges``);
- ``aruco-none``, ``aruco-subpix``, ``aruco-contour``: cv2.aruco with that corner refinement;
- ``aruco-apriltag-whole``: cv2.aruco with ``CORNER_REFINE_APRILTAG`` (AprilTag's quad search
  over the whole image), its corners as cv2.aruco gives them;
- ``aruco-apriltag-window``: percept's ``aruco`` detector with ``apriltag`` refinement
  (ArUco's search, AprilTag's corners in a window around each marker);
- ``aruco-edges``: percept's ``aruco`` detector with ``edges`` refinement (cv2.aruco's search
  and reading, corners fitted to the edges);
- ``apriltag-d1``, ``apriltag-d2``: the AprilTag C library (pupil-apriltags) at decimation 1, 2;
- ``follow``: percept's windowed following (``percept.perception.landmarks.follow``): the default
  detector in a window around each tag predicted 3 px off its true corners (time only: recall
  and corners are the same detector's).

A detection matches a tag of its id whose centre is within half the tag's size; a detection
matching no tag is a false positive. Corner error: distance of each corner to the truth. Time:
ms per 640x480 picture on one thread (``cv2.setNumThreads(1)``, ``nthreads=1``), as wall-clock
time and as the process's CPU time (on one thread the work itself, whatever else the machine
runs: on a shared machine the wall-clock time grows with the load, the CPU time much less).

    python bench/bench_markers.py [--per-degradation 12] [--seed 0] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cv2
import numpy as np

from percept.perception.evaluation.marker_photos import (
    DEGRADATIONS,
    TagPicture,
    TagTruth,
    match,
    picture_set,
)
from percept.perception.landmarks.detection.detector import Marker, MarkerDetector, load_dictionary
from percept.perception.landmarks.follow import window
from percept.perception.landmarks.settings import LandmarkSettings

REPO = Path(__file__).resolve().parents[1]
TUTORIAL = REPO.parent / "shared" / "data" / "opencv-aruco-tutorial"
BINS = ((10, 12), (12, 20), (20, 40), (40, 80), (80, 200))
DETECTORS = (
    "percept",
    "aruco-none",
    "aruco-subpix",
    "aruco-contour",
    "aruco-apriltag-whole",
    "aruco-apriltag-window",
    "aruco-edges",
    "apriltag-d1",
    "apriltag-d2",
)


class _Whole:
    """cv2.aruco with its own AprilTag refinement over the whole image."""

    def __init__(self, dictionary: str) -> None:
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
        self._detector = cv2.aruco.ArucoDetector(load_dictionary(dictionary), params)

    def detect(self, image: np.ndarray) -> list[Marker]:
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        corners, ids, _ = self._detector.detectMarkers(gray)
        if ids is None:
            return []
        return [
            Marker(int(i), c.reshape(4, 2).astype(float))
            for i, c in zip(ids.ravel(), corners, strict=True)
        ]


def make(name: str, dictionary: str = "DICT_APRILTAG_36h11", file: Path | None = None):
    if name == "aruco-apriltag-whole":
        return _Whole(dictionary) if file is None else None
    if name.startswith("apriltag-d"):
        if file is not None:
            return None
        return MarkerDetector(dictionary, detector="apriltag", decimation=int(name[-1]))
    if name == "percept":
        return MarkerDetector(dictionary, file, detector="percept")
    refinement = "apriltag" if name == "aruco-apriltag-window" else name.split("-")[1]
    return MarkerDetector(dictionary, file, corner_refinement=refinement, detector="aruco")


def evaluate(name: str, pictures: list[TagPicture]) -> dict:
    detector = make(name)
    seen = {b: 0 for b in BINS}
    hits = {b: 0 for b in BINS}
    per_degradation = {d: [0, 0] for d in DEGRADATIONS}
    errors: list[float] = []
    false_positives = 0
    ms: list[float] = []
    cpu: list[float] = []
    for p in pictures:
        began, began_cpu = time.perf_counter(), time.process_time()
        found = detector.detect(p.image)
        if p.image.shape[1] == 640:
            ms.append((time.perf_counter() - began) * 1000)
            cpu.append((time.process_time() - began_cpu) * 1000)
        pairs, unmatched = match(found, p.tags)
        false_positives += len(unmatched)
        matched = dict(pairs)
        for ti, t in enumerate(p.tags):
            if not t.findable:
                continue
            b = next(b for b in BINS if b[0] <= t.size < b[1]) if t.size >= BINS[0][0] else None
            if b is None:
                continue
            seen[b] += 1
            if b[0] >= 20:
                per_degradation[p.degradation][0] += 1
            if ti in matched:
                hits[b] += 1
                if b[0] >= 20:
                    per_degradation[p.degradation][1] += 1
                err = np.linalg.norm(found[matched[ti]].corners - t.corners, axis=1)
                errors.extend(float(e) for e in err)
    return {
        "detector": name,
        "recall": {f"{lo}-{hi}": (hits[(lo, hi)], seen[(lo, hi)]) for lo, hi in BINS},
        "recall_20px_by_degradation": {d: tuple(v[::-1]) for d, v in per_degradation.items()},
        "corner_median": float(np.median(errors)) if errors else None,
        "corner_p90": float(np.percentile(errors, 90)) if errors else None,
        "false_positives": false_positives,
        "ms_median": float(np.median(ms)),
        "ms_p90": float(np.percentile(ms, 90)),
        "cpu_ms_median": float(np.median(cpu)),
        "cpu_ms_p90": float(np.percentile(cpu, 90)),
    }


def follow_ms(pictures: list[TagPicture]) -> dict:
    """Time of following every tag of >= 12 px in its window, from corners 3 px off."""
    detector = MarkerDetector.from_settings(LandmarkSettings())
    camera_size = (640, 480)
    rng = np.random.default_rng(0)
    ms, per_tag, per_tag_cpu, found, tried = [], [], [], 0, 0
    for p in pictures:
        if p.image.shape[1] != camera_size[0]:
            continue
        tags = [t for t in p.tags if t.findable and t.size >= 12]
        expected = [t.corners + rng.normal(0, 3 / np.sqrt(2), 2) for t in tags]
        began, began_cpu = time.perf_counter(), time.process_time()
        gray = detector.prepare(p.image)
        hits = []
        for t, c in zip(tags, expected, strict=True):
            box = window(c, *camera_size)
            if box is not None:
                hits.append(any(m.id == t.id for m in detector.detect_prepared(gray, box)))
        ms.append((time.perf_counter() - began) * 1000)
        per_tag.append(ms[-1] / max(len(tags), 1))
        per_tag_cpu.append((time.process_time() - began_cpu) * 1000 / max(len(tags), 1))
        found += sum(hits)
        tried += len(tags)
    return {
        "detector": "follow",
        "followed": (found, tried),
        "ms_per_tag_median": float(np.median(per_tag)),
        "cpu_ms_per_tag_median": float(np.median(per_tag_cpu)),
        "ms_median": float(np.median(ms)),
        "ms_p90": float(np.percentile(ms, 90)),
    }


def tutorial() -> dict:
    """Markers found and corner error on OpenCV's tutorial photos, per detector."""
    if not TUTORIAL.is_dir():
        return {}
    gold = json.loads((TUTORIAL / "gold_markers.json").read_text(encoding="utf-8"))
    out = {}
    for name in DETECTORS:
        found_all, total, errors = 0, 0, []
        for image_name, g in gold.items():
            if "markers" not in g:  # the diamond photo: ids only
                continue
            dictionary = g["dictionary"]
            file = (
                TUTORIAL / dictionary.split(":", 1)[1] if dictionary.startswith("custom:") else None
            )
            try:
                detector = make(name, dictionary if file is None else "DICT_4X4_50", file)
            except Exception:
                detector = None
            if detector is None:
                continue
            found = detector.detect(cv2.imread(str(TUTORIAL / image_name)))
            truth = [TagTruth(m["id"], np.array(m["corners_xy"], float)) for m in g["markers"]]
            pairs, _ = match(found, truth)
            total += len(truth)
            found_all += len(pairs)
            for ti, di in pairs:
                errors.extend(
                    np.linalg.norm(found[di].corners - truth[ti].corners, axis=1).tolist()
                )
        if total:
            out[name] = {
                "found": (found_all, total),
                "corner_median": float(np.median(errors)) if errors else None,
            }
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--per-degradation", type=int, default=12, help="pictures per degradation")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    cv2.setNumThreads(1)
    pictures = picture_set(args.seed, args.per_degradation)
    tags = sum(len(p.tags) for p in pictures)
    rows = [evaluate(name, pictures) for name in DETECTORS]
    rows.append(follow_ms(pictures))
    result = {"pictures": len(pictures), "tags": tags, "rows": rows, "tutorial": tutorial()}
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"{len(pictures)} pictures, {tags} tags")
    head = "detector                 " + " ".join(f"{lo:>3}-{hi:<3}" for lo, hi in BINS)
    print(head + "  corner med/p90  FP  ms med/p90  cpu ms med/p90")
    for r in rows:
        if "recall" not in r:
            f, t = r["followed"]
            print(
                f"{r['detector']:<24} followed {f}/{t}  {r['ms_median']:.2f}/{r['ms_p90']:.2f}"
                f" per picture, {r['ms_per_tag_median']:.2f} per tag"
                f" (cpu {r['cpu_ms_per_tag_median']:.2f})"
            )
            continue
        cells = " ".join(
            f"{100 * h / n:6.1f}%" if n else "     - " for h, n in r["recall"].values()
        )
        print(
            f"{r['detector']:<24} {cells}  {r['corner_median']:.3f}/{r['corner_p90']:.3f}"
            f"  {r['false_positives']:>3}  {r['ms_median']:.2f}/{r['ms_p90']:.2f}"
            f"  {r['cpu_ms_median']:.2f}/{r['cpu_ms_p90']:.2f}"
        )
    print("tags in each bin:", {k: n for k, (_, n) in rows[0].get("recall", {}).items()})
    print("recall of tags >= 20 px by degradation:")
    for r in rows:
        if "recall_20px_by_degradation" in r:
            cells = " ".join(
                f"{d}={h}/{n}" for d, (h, n) in r["recall_20px_by_degradation"].items()
            )
            print(f"  {r['detector']:<24} {cells}")
    print("OpenCV tutorial photos (corners to 1 px):")
    for name, r in result["tutorial"].items():
        f, t = r["found"]
        print(f"  {name:<24} {f}/{t} markers, corner median {r['corner_median']}")


if __name__ == "__main__":
    main()
