"""Marker landmarks: detection on OpenCV's tutorial photos, box poses on rendered boxes."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.config.loader import ConfigError, build
from percept.kinematics.pose import CameraPose, rpy_matrix, wrap
from percept.perception.evaluation.markers import PlacedBox, render
from percept.perception.landmarks.boxes import BoxEstimator
from percept.perception.landmarks.detection.detector import (
    LandmarkError,
    MarkerDetector,
    load_dictionary,
)
from percept.perception.landmarks.geometry import circular_mean, marker_in_box
from percept.perception.landmarks.pose import candidate_poses, marker_in_ground, upright_and_facing
from percept.perception.landmarks.records import BoxPose, average, box_error
from percept.perception.landmarks.settings import LandmarkSettings
from percept.runtime.cli import main
from tests.support.landmarks import BOX, CAMERA

DATA = Path(__file__).resolve().parents[4] / "shared" / "data" / "opencv-aruco-tutorial"
REPO = Path(__file__).resolve().parents[3]


def _gold() -> dict:
    if not DATA.is_dir():
        pytest.skip(f"public test data not found at {DATA}")
    return json.loads((DATA / "gold_markers.json").read_text(encoding="utf-8"))


def _detector(dictionary: str, refinement: str = "none", detector: str = "aruco") -> MarkerDetector:
    if dictionary.startswith("custom:"):
        return MarkerDetector(
            dictionary_file=DATA / dictionary.split(":", 1)[1],
            corner_refinement=refinement,
            detector=detector,
        )
    return MarkerDetector(dictionary, corner_refinement=refinement, detector=detector)


@pytest.mark.parametrize(
    "image",
    ["singlemarkersoriginal.jpg", "gboriginal.png", "choriginal.jpg", "chocclusion_original.jpg"],
)
def test_gold_ids_and_corners(image: str) -> None:
    # OpenCV's own test pins these with its default detector: no corner refinement.
    gold = _gold()[image]
    found = {
        m.id: m.corners for m in _detector(gold["dictionary"]).detect(cv2.imread(str(DATA / image)))
    }
    assert sorted(found) == sorted(m["id"] for m in gold["markers"])
    for m in gold["markers"]:
        err = np.abs(found[m["id"]] - np.array(m["corners_xy"], dtype=float)).max()
        assert err <= gold["tolerance_px"], (m["id"], err)


@pytest.mark.parametrize(
    "image",
    ["singlemarkersoriginal.jpg", "gboriginal.png", "choriginal.jpg", "chocclusion_original.jpg"],
)
def test_apriltag_windows_match_a_whole_image_apriltag_search(image: str) -> None:
    # The detector refines in a window around each marker ArUco finds; cv2.aruco's AprilTag
    # refinement searches the whole image. Both must give the same markers and corners.
    gold = _gold()[image]
    name = gold["dictionary"]
    custom = name.startswith("custom:")
    dictionary = (
        load_dictionary(file=DATA / name.split(":", 1)[1]) if custom else load_dictionary(name)
    )
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
    gray = cv2.imread(str(DATA / image), cv2.IMREAD_GRAYSCALE)
    corners, ids, _rejected = cv2.aruco.ArucoDetector(dictionary, params).detectMarkers(gray)
    whole = {int(i): c.reshape(4, 2) - 0.5 for i, c in zip(ids.ravel(), corners, strict=True)}
    found = {m.id: m.corners for m in _detector(name, "apriltag").detect(gray)}
    assert sorted(found) == sorted(whole)
    for i, c in whole.items():
        assert np.abs(found[i] - c).max() < 1e-3, i


def test_otsu_threshold_finds_the_same_markers() -> None:
    gold = _gold()["singlemarkersoriginal.jpg"]
    detector = MarkerDetector(
        "DICT_6X6_250", threshold="otsu", corner_refinement="none", detector="aruco"
    )
    found = detector.detect(cv2.imread(str(DATA / "singlemarkersoriginal.jpg")))
    assert sorted(m.id for m in found) == sorted(m["id"] for m in gold["markers"])


def test_unknown_dictionary_is_refused() -> None:
    with pytest.raises(LandmarkError, match="DICT_APRILTAG_36h11"):
        load_dictionary("DICT_NOPE")


def test_cli_json_lines_with_poses(capsys: pytest.CaptureFixture[str]) -> None:
    gold = _gold()["singlemarkersoriginal.jpg"]
    image = str(DATA / "singlemarkersoriginal.jpg")
    args = ["markers", image, image, "--dict", "DICT_6X6_250", "--refinement", "none"]
    args += ["--camera", str(DATA / "tutorial_camera_params.yml"), "--marker-size", "0.05"]
    assert main([*args, "--json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(lines) == 2 and lines[0]["image"] == image
    by_id = {m["id"]: m for m in lines[0]["markers"]}
    for m in gold["markers"]:
        assert np.abs(np.array(by_id[m["id"]]["corners"]) - m["corners_xy"]).max() <= 1.0
        pose = by_id[m["id"]]["pose"]
        assert pose["error"] < 1.0
        assert 0.2 < pose["tvec"][2] < 3.0  # in front of the camera, at a desk's distance


def _random_view(rng: np.random.Generator) -> tuple[CameraPose, PlacedBox]:
    """A box 0.45-0.9 m away and the camera (0.45 m high) looking at it, roughly."""
    distance, bearing = rng.uniform(0.45, 0.9), rng.uniform(-0.6, 0.6)
    pitch = math.atan2(0.45 - 0.08, distance) + rng.uniform(-0.1, 0.1)
    yaw = bearing + rng.uniform(-0.2, 0.2)
    camera_pose = CameraPose(rpy_matrix((0.0, pitch, yaw)), np.array([0.0, 0.0, 0.45]))
    box = PlacedBox(
        BOX, distance * math.cos(bearing), distance * math.sin(bearing), rng.uniform(-3.1, 3.1)
    )
    return camera_pose, box


@pytest.mark.parametrize("box_fit", ["ground", "average"])
def test_box_poses_from_rendered_markers(box_fit: str) -> None:
    settings = LandmarkSettings(boxes=(BOX,), box_fit=box_fit)
    rng = np.random.default_rng(7)
    errors = []
    for _ in range(12):
        camera_pose, placed = _random_view(rng)
        estimator = BoxEstimator(settings, CAMERA)
        assert estimator.process(render(settings, [placed], CAMERA, camera_pose), camera_pose, 0.0)
        (pose,) = estimator.boxes(0.0)
        errors.append(box_error(pose, placed.x, placed.y, placed.theta))
    position, heading = np.array(errors).T
    assert position.max() < 0.02 and np.degrees(heading.max()) < 2.0, (position, heading)


def test_ambiguity_resolved_by_upright_markers() -> None:
    settings = LandmarkSettings(boxes=(BOX,), corner_refinement="none")
    camera_pose = CameraPose(rpy_matrix((0.0, 0.6, 0.0)), np.array([0.0, 0.0, 0.45]))
    placed = PlacedBox(BOX, 0.6, 0.0, math.pi - 0.2)
    (marker,) = MarkerDetector(corner_refinement="none", detector="aruco").detect(
        render(settings, [placed], CAMERA, camera_pose)
    )
    candidates = candidate_poses(marker.corners, 0.1, CAMERA)
    fits = [
        upright_and_facing(marker_in_ground(c, camera_pose), camera_pose, 0.5) for c in candidates
    ]
    assert fits.count(True) == 1
    chosen = candidates[fits.index(True)]
    truth = placed.matrix() @ marker_in_box(BOX, BOX.markers[0])
    normal = marker_in_ground(chosen, camera_pose)[:3, 2]
    assert math.degrees(math.acos(float(normal @ truth[:3, 2]))) < 5.0


def test_every_kth_frame_and_forgetting() -> None:
    settings = LandmarkSettings(boxes=(BOX,), every=3, forget_after=1.0)
    camera_pose, placed = _random_view(np.random.default_rng(3))
    image = render(settings, [placed], CAMERA, camera_pose)
    estimator = BoxEstimator(settings, CAMERA)
    searched = [estimator.process(image, camera_pose, t * 0.1) for t in range(7)]
    assert searched == [True, False, False, True, False, False, True]
    assert estimator.boxes(0.6)[0].id == 1
    assert estimator.boxes(0.6 + 1.01) == []


def test_window_averages_headings_across_the_wrap() -> None:
    poses = [BoxPose(3, 1.0, 0.0, math.pi - 0.02), BoxPose(3, 1.2, 0.2, -math.pi + 0.04, n=2)]
    mean = average(poses)
    assert mean.n == 3
    assert mean.x == pytest.approx((1.0 + 2 * 1.2) / 3) and mean.y == pytest.approx(0.4 / 3)
    assert abs(wrap(mean.theta - (math.pi + 0.02))) < 1e-3
    assert circular_mean([0.1, -0.1]) == pytest.approx(0.0, abs=1e-12)


def test_settings_reject_bad_boxes() -> None:
    bad_fit = {"boxes": [{"id": 1, "size": [0.1, 0.1, 0.1], "markers": [{"id": 0, "side": 0.2}]}]}
    with pytest.raises(ConfigError, match="does not fit"):
        build(LandmarkSettings, bad_fit, "x.toml", "landmarks")
    twice = {
        "boxes": [
            {"id": 1, "size": [0.2, 0.2, 0.2], "markers": [{"id": 4, "side": 0.1}]},
            {"id": 2, "size": [0.2, 0.2, 0.2], "markers": [{"id": 4, "side": 0.1}]},
        ]
    }
    with pytest.raises(ConfigError, match="duplicate marker id: 4"):
        build(LandmarkSettings, twice, "x.toml", "landmarks")
    with pytest.raises(ConfigError, match="landmarks: unknown marker dictionary 'DICT_NOPE'"):
        build(LandmarkSettings, {"dictionary": "DICT_NOPE"}, "x.toml", "landmarks")


def test_shipped_experiment_boxes_are_consistent() -> None:
    from percept.runtime.settings.experiment import load_experiment

    landmarks = load_experiment(REPO / "config" / "experiments" / "tabletop.toml").landmarks
    assert len(landmarks.boxes) >= 1
    load_dictionary(landmarks.dictionary, landmarks.dictionary_file)


def test_markers_boxes_and_peer_pose_in_the_simulated_world() -> None:
    from percept.runtime.net.peers import peer_pose
    from percept.runtime.settings.experiment import load_experiment
    from percept.runtime.settings.scene import open_world

    landmarks = load_experiment(REPO / "config" / "experiments" / "tabletop.toml").landmarks
    boxes = {}
    with open_world("tabletop-basic") as world:
        t = 5.0
        truth = world.truth(t)
        for robot in world.robots:
            record = truth.record(robot)
            image = world.render(robot, t)
            camera_pose = world.robot_model(robot).tree.camera_pose(truth.robots[robot].joints)
            estimator = BoxEstimator(landmarks, world.camera_model(robot))
            sightings = estimator.observe(estimator.detector.detect(image), camera_pose, t)
            shown = {
                m["id"]: np.array(m["corners"])
                for b in record["boxes"]
                for m in b["markers"]
                if m["facing"] and m["in_image"]
            }
            assert sightings, robot
            for s in sightings:  # corners against the simulator's projection of the markers
                assert np.abs(s.marker.corners - shown[s.marker.id]).max() < 1.0
            boxes[robot] = estimator.boxes(t)
            real = {b["id"]: b["ground"] for b in record["boxes"]}
            for b in boxes[robot]:
                position, heading = box_error(b, *real[b.id])
                assert position < 0.02 and math.degrees(heading) < 2.0, (robot, b)
        pose = peer_pose(boxes["a"], boxes["b"])
        (b_seen,) = [r["ground"] for r in truth.record("a")["robots"] if r["name"] == "b"]
        assert pose is not None
        assert math.hypot(pose.x - b_seen[0], pose.y - b_seen[1]) < 0.03
        assert math.degrees(abs(wrap(pose.theta - b_seen[2]))) < 3.0


@pytest.mark.parametrize(
    "image",
    ["singlemarkersoriginal.jpg", "gboriginal.png", "choriginal.jpg", "chocclusion_original.jpg"],
)
def test_percept_detector_finds_the_gold_markers(image: str) -> None:
    # percept's own reading of cv2.aruco's quads, on 6x6 and custom dictionaries. The gold
    # corners are OpenCV's integer ones, given to 1 px, and they lie about half a pixel inside
    # the square (a contour runs through its dark pixels): the fitted corners are checked
    # against them to 2 px, and against AprilTag's sub-pixel corners closely.
    gold = _gold()[image]
    gray = cv2.imread(str(DATA / image), cv2.IMREAD_GRAYSCALE)
    found = {
        m.id: m.corners for m in _detector(gold["dictionary"], "edges", "percept").detect(gray)
    }
    apriltag = {m.id: m.corners for m in _detector(gold["dictionary"], "apriltag").detect(gray)}
    assert sorted(found) == sorted(m["id"] for m in gold["markers"])
    for m in gold["markers"]:
        err = np.abs(found[m["id"]] - np.array(m["corners_xy"], dtype=float)).max()
        assert err <= 2 * gold["tolerance_px"], (m["id"], err)
    apart = [float(np.abs(found[i] - c).max()) for i, c in apriltag.items()]
    assert np.median(apart) <= 0.6, apart
