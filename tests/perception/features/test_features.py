"""Sensory experiences and their scaling, on objects of known geometry."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, rpy_matrix
from percept.kinematics.tree import KinematicTree
from percept.perception.features.experience import (
    FEATURES,
    FeatureSettings,
    SensoryExperience,
    SensoryMemory,
    bbox_edge_pixels,
    sensory_experience,
)
from percept.perception.features.footprint import BALL_CHI2, MIN_COUNT, fit_ball
from percept.perception.features.scaling import (
    DEFAULT_STATS,
    FeatureScaling,
    FeatureStats,
    ScalingSettings,
)
from percept.runtime.cli import main
from percept.runtime.settings.profile import load_profile

REPO = Path(__file__).resolve().parents[3]
OP3 = REPO / "config" / "robots" / "robotis-op3.toml"
FLAT = np.full((3, 16), 1 / 16)
CHAPTER = FeatureSettings(model="chapter")


def _box_points(size: tuple[float, float, float], x: float, y: float, yaw: float) -> np.ndarray:
    sx, sy, h = size
    corners = np.array(
        [[a * sx / 2, b * sy / 2, c * h] for a in (-1, 1) for b in (-1, 1) for c in (0, 1)]
    )
    R = rpy_matrix((0.0, 0.0, yaw))
    return corners @ R.T + [x, y, 0.0]


def _cylinder_points(d: float, h: float, x: float, y: float) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, 180, endpoint=False)
    ring = np.column_stack([d / 2 * np.cos(a) + x, d / 2 * np.sin(a) + y])
    return np.vstack(
        [np.column_stack([ring, np.zeros(180)]), np.column_stack([ring, np.full(180, h)])]
    )


def _frustum_points(d: float, h: float, k: float, x: float, y: float) -> np.ndarray:
    """Rim points of an upright frustum: bottom diameter d, top diameter k d (k = 0: a cone)."""
    bottom = _cylinder_points(d, 0.0, x, y)[:180]
    top = _cylinder_points(k * d, h, x, y)[180:]
    return np.vstack([bottom, top])


def _ball_points(d: float, x: float, y: float) -> np.ndarray:
    """Points all over a ball of diameter d lying on the ground at x, y."""
    lat, lon = np.meshgrid(np.linspace(-np.pi / 2, np.pi / 2, 91), np.linspace(0, 2 * np.pi, 180))
    unit = np.column_stack(
        [
            (np.cos(lat) * np.cos(lon)).ravel(),
            (np.cos(lat) * np.sin(lon)).ravel(),
            np.sin(lat).ravel(),
        ]
    )
    return unit * (d / 2) + [x, y, d / 2]


def _area(cam: CameraModel, pose: CameraPose, points: np.ndarray) -> float:
    """Area in square pixels of the points' image (their convex hull: the solids are convex)."""
    import cv2

    uv = cam.project((points - pose.t) @ pose.R).astype(np.float32)
    return float(cv2.contourArea(cv2.convexHull(uv)))


def _outline(cam: CameraModel, pose: CameraPose, points: np.ndarray) -> tuple[float, ...]:
    """The exact (sub-pixel) bounding box of the points' image, as (left, top, width, height)
    in the whole-pixel convention of sensory_experience (edges half a pixel out)."""
    uv = cam.project((points - pose.t) @ pose.R)
    (u0, v0), (u1, v1) = uv.min(axis=0), uv.max(axis=0)
    return (u0 + 0.5, v0 + 0.5, u1 - u0, v1 - v0)


def _pixels(cam: CameraModel, pose: CameraPose, points: np.ndarray) -> tuple[int, ...] | None:
    """The bounding box of the pixels whose centres the object covers, as a segmentation gives
    it; None when the object is not wholly inside the image."""
    uv = cam.project((points - pose.t) @ pose.R)
    if not np.isfinite(uv).all():
        return None
    left, top = math.ceil(uv[:, 0].min()), math.ceil(uv[:, 1].min())
    right, bottom = math.floor(uv[:, 0].max()), math.floor(uv[:, 1].max())
    if left < 0 or top < 0 or right >= cam.width or bottom >= cam.height:
        return None
    if right < left or bottom < top:
        return None
    return (left, top, right - left + 1, bottom - top + 1)


@pytest.fixture(scope="module")
def op3() -> tuple[KinematicTree, CameraModel]:
    p = load_profile(OP3)
    tree = KinematicTree.from_settings(p.kinematics)
    return tree, CameraModel.from_lens(p.camera.lens, p.camera.width, p.camera.height)


def test_bbox_edges_follow_opencv_pixel_centres() -> None:
    edges = bbox_edge_pixels((10, 20, 4, 6))
    assert edges.tolist() == [[11.5, 25.5], [9.5, 25.5], [13.5, 25.5], [11.5, 19.5]]


@pytest.mark.parametrize("pan", [0.0, 0.6, -0.9])
def test_card_in_the_middle_of_the_view_is_exact_with_the_chapter_model(op3, pan) -> None:
    tree, cam = op3
    pose = tree.camera_pose({"head_pan": pan, "head_tilt": -0.5})
    optical = pose.R[:, 0]
    bearing = math.atan2(optical[1], optical[0])
    # The optical axis meets the ground here; put an upright card there, facing the camera.
    reach = pose.t[2] / -optical[2]
    centre = pose.t[:2] + reach * optical[:2]
    card = _box_points((1e-9, 0.12, 0.08), *centre, bearing)
    exp = sensory_experience(_outline(cam, pose, card), FLAT, cam, pose, CHAPTER)
    assert exp.on_ground
    assert (exp.x, exp.y) == pytest.approx(tuple(centre), abs=1e-9)
    assert exp.height == pytest.approx(0.08, abs=1e-9)
    # Its width is taken at the bottom edge's distance from the lower corners' columns, which the
    # top edge sets: it is nearer along the optical axis, so it looks wider.
    depth_bottom = (np.array([*centre, 0.0]) - pose.t) @ optical
    depth_top = (np.array([*centre, 0.08]) - pose.t) @ optical
    assert exp.width == pytest.approx(0.12 * depth_bottom / depth_top, abs=1e-9)


@pytest.mark.parametrize("bearing", [0.0, 0.5, -0.9])
def test_cylinder_anywhere_in_view_is_found_by_the_cylinder_model(op3, bearing) -> None:
    tree, cam = op3
    pose = tree.camera_pose({"head_pan": bearing * 0.8, "head_tilt": -0.6})
    for distance, d, h in ((0.35, 0.06, 0.1), (0.8, 0.1, 0.05), (1.6, 0.08, 0.2)):
        x, y = distance * math.cos(bearing), distance * math.sin(bearing)
        exp = sensory_experience(_outline(cam, pose, _cylinder_points(d, h, x, y)), FLAT, cam, pose)
        # The fit uses a 16-sided prism for the circle: within 2 % of its size.
        assert math.hypot(exp.x - x, exp.y - y) < 0.02 * d
        assert exp.width == pytest.approx(d, rel=0.02)
        assert exp.height == pytest.approx(h, rel=0.01)
        # The chapter's construction measures the front, and the far rim of the top.
        ch = sensory_experience(
            _outline(cam, pose, _cylinder_points(d, h, x, y)), FLAT, cam, pose, CHAPTER
        )
        assert math.hypot(ch.x - x, ch.y - y) == pytest.approx(d / 2, rel=0.02)
        assert ch.height > h * 1.05


@pytest.mark.parametrize("bearing", [0.0, 0.5, -0.9])
def test_solid_model_finds_cones_frusta_and_balls(op3, bearing) -> None:
    """Exact bounding boxes and silhouette areas: the solid model recovers what the cylinder
    model reads too low."""
    tree, cam = op3
    pose = tree.camera_pose({"head_pan": bearing * 0.8, "head_tilt": -0.6})
    for distance, d, h, k in ((0.4, 0.06, 0.1, 0.0), (0.9, 0.1, 0.08, 0.4), (1.6, 0.08, 0.12, 0.0)):
        x, y = distance * math.cos(bearing), distance * math.sin(bearing)
        points = _frustum_points(d, h, k, x, y)
        bbox, area = _outline(cam, pose, points), _area(cam, pose, points)
        exp = sensory_experience(bbox, FLAT, cam, pose, pixels=area)
        assert math.hypot(exp.x - x, exp.y - y) < 0.03 * d
        assert exp.width == pytest.approx(d, rel=0.03)
        assert exp.height == pytest.approx(h, rel=0.03)
        cylinder = sensory_experience(bbox, FLAT, cam, pose, FeatureSettings(model="cylinder"))
        assert cylinder.height < 0.96 * h
    for distance, d in ((0.35, 0.05), (1.0, 0.1), (1.5, 0.1)):
        x, y = distance * math.cos(bearing), distance * math.sin(bearing)
        points = _ball_points(d, x, y)
        bbox, area = _outline(cam, pose, points), _area(cam, pose, points)
        exp = sensory_experience(bbox, FLAT, cam, pose, pixels=area)
        assert math.hypot(exp.x - x, exp.y - y) < 0.02 * d
        assert exp.width == pytest.approx(d, rel=0.02)
        assert exp.height == pytest.approx(d, rel=0.02)
        cylinder = sensory_experience(bbox, FLAT, cam, pose, FeatureSettings(model="cylinder"))
        assert cylinder.height < 0.9 * d


def test_sensory_memory_keeps_each_anchors_shape_between_choices(op3) -> None:
    """Frame after frame with the head panning: an anchor's shape is chosen every
    ``shape_every`` frames and fitted again in between, with the same features as choosing in
    every frame; a frame without a count keeps the shape, and dead anchors are forgotten."""
    tree, cam = op3
    objects = {
        "o1": _frustum_points(0.08, 0.12, 0.0, 0.9, 0.1),  # a cone
        "o2": _ball_points(0.08, 0.7, -0.25),
        "o3": _cylinder_points(0.06, 0.1, 1.1, 0.3),
    }
    memory = SensoryMemory(cam, FeatureSettings(shape_every=5))
    for frame, pan in enumerate(np.linspace(-0.3, 0.3, 12)):
        pose = tree.camera_pose({"head_pan": float(pan), "head_tilt": -0.6})
        for anchor_id, points in objects.items():
            bbox, area = _outline(cam, pose, points), _area(cam, pose, points)
            fresh = sensory_experience(bbox, FLAT, cam, pose, pixels=area)
            counted = None if (frame == 7 and anchor_id == "o2") else area
            kept = memory.experience(anchor_id, bbox, FLAT, pose, pixels=counted)
            if counted is None:  # the cylinder model for this frame only
                cylinder = sensory_experience(bbox, FLAT, cam, pose, FeatureSettings("cylinder"))
                assert kept.height == pytest.approx(cylinder.height, rel=1e-6)
                continue
            for name in ("x", "y", "width", "height"):
                assert getattr(kept, name) == pytest.approx(getattr(fresh, name), rel=0.01)
        memory.next_frame(objects)
    shapes = {i: f.solid.shape for i, f in memory._fits.items()}
    assert shapes == {"o1": "frustum", "o2": "ball", "o3": "cylinder"}
    assert memory._fits["o2"].decided == 10  # chosen in frames 0, 5 and 10: 7 had no count
    memory.next_frame(["o1"])
    assert set(memory._fits) == {"o1"}


def test_sensory_memory_reuses_an_unchanged_sighting_and_refits_a_changed_one(op3) -> None:
    """With the head still, an anchor in the same box with (nearly) the same pixel count keeps
    its spatial features without a fit, the same as fitting afresh gives; its colour is read
    in every frame. A box moved by one pixel, another camera pose or a pixel count changed by
    more than the tolerance is fitted again."""
    tree, cam = op3
    pose = tree.camera_pose({"head_pan": 0.2, "head_tilt": -0.6})
    cone = _frustum_points(0.08, 0.12, 0.0, 0.9, 0.1)
    bbox = tuple(float(round(v)) for v in _outline(cam, pose, cone))
    area = round(_area(cam, pose, cone))
    memory = SensoryMemory(cam)
    first = memory.experience("o1", bbox, FLAT, pose, pixels=area)
    red = np.zeros((3, 16))
    red[:, [3, 12, 6]] = 1.0  # another colour, same box
    same_pose = CameraPose(R=pose.R.copy(), t=pose.t.copy())  # equal, not the same object
    memory.next_frame(["o1"])
    kept = memory.experience("o1", bbox, red, same_pose, pixels=area + 1)
    assert memory.reused == 1
    fresh = sensory_experience(bbox, red, cam, pose, pixels=area + 1)
    assert kept.features() == {**first.features(), **_colour(fresh)}
    for name in ("x", "y", "width", "height"):
        assert getattr(kept, name) == pytest.approx(getattr(fresh, name), rel=1e-4)
    moved = (bbox[0] + 1, *bbox[1:])
    turned = tree.camera_pose({"head_pan": 0.21, "head_tilt": -0.6})
    more = area + max(2, area // 100)
    for k, (box, seen_from, pixels) in enumerate(
        [(moved, pose, area), (bbox, turned, area), (bbox, pose, more)]
    ):
        memory.next_frame(["o1"])
        refit = memory.experience("o1", box, FLAT, seen_from, pixels=pixels)
        assert memory.reused == 1, k
        afresh = sensory_experience(box, FLAT, cam, seen_from, pixels=pixels)
        for name in ("x", "y", "width", "height"):
            assert getattr(refit, name) == pytest.approx(getattr(afresh, name), rel=1e-3), k
    assert memory.experience("o1", bbox, FLAT, pose, pixels=None) != first  # no count: a cylinder
    memory.next_frame([])
    assert memory.experience("o1", bbox, FLAT, pose, pixels=area) == first  # forgotten: afresh


def test_sensory_memory_refits_for_a_changed_pixel_count_only_where_the_fit_reads_it(op3) -> None:
    """With the head still and the boxes unchanged, a count that flickers (by more than the
    tolerance, as by a cell of perception's grid) is read only by a ball's fit and by the
    choice of a shape: a frustum keeps its features between its shape choices, the same as
    fitting it again gives; a ball is fitted again; a frustum's shape is chosen again when it
    is due."""
    tree, cam = op3
    pose = tree.camera_pose({"head_pan": 0.2, "head_tilt": -0.6})
    solids = {
        "cone": _frustum_points(0.08, 0.12, 0.0, 0.9, 0.1),
        "ball": _ball_points(0.08, 0.7, -0.25),
    }
    boxes = {i: tuple(float(round(v)) for v in _outline(cam, pose, p)) for i, p in solids.items()}
    areas = {i: round(_area(cam, pose, p)) for i, p in solids.items()}
    memory = SensoryMemory(cam, FeatureSettings(shape_every=3))
    first = {i: memory.experience(i, boxes[i], FLAT, pose, pixels=areas[i]) for i in solids}
    assert {i: f.solid.shape for i, f in memory._fits.items()} == {
        "cone": "frustum",
        "ball": "ball",
    }
    for frame in (1, 2, 3):
        memory.next_frame(solids)
        flicker = {i: a + (max(4, a // 100) if frame % 2 else 0) for i, a in areas.items()}
        reused = memory.reused
        cone = memory.experience("cone", boxes["cone"], FLAT, pose, pixels=flicker["cone"])
        if frame < 3:  # between choices: kept, as a refit (which reads the box alone) gives
            assert memory.reused == reused + 1 and cone == first["cone"]
            refit = SensoryMemory(cam, FeatureSettings(shape_every=3))
            refit.experience("cone", boxes["cone"], FLAT, pose, pixels=areas["cone"])
            refit.next_frame(["cone"])
            assert (
                refit.experience("cone", boxes["cone"], FLAT, pose, pixels=flicker["cone"]) == cone
            )
        else:  # the shape chosen again: with this count
            assert memory.reused == reused and memory._fits["cone"].decided == 3
        reused = memory.reused
        memory.experience("ball", boxes["ball"], FLAT, pose, pixels=flicker["ball"])
        assert memory.reused == reused, frame  # a ball: fitted again


def _colour(exp: SensoryExperience) -> dict[str, float | None]:
    return {k: v for k, v in exp.features().items() if k in FEATURES[4:]}


def test_solid_model_reads_boxes_and_cylinders_as_cylinders(op3) -> None:
    """A square block seen corner-on or face-on, and a cylinder: the pixel count is a
    cylinder's or more than the least a box has, so the answer is the cylinder fit's; without
    a usable pixel count it is too."""
    tree, cam = op3
    pose = tree.camera_pose({"head_pan": 0.3, "head_tilt": -0.6})
    x, y = 0.8 * math.cos(0.35), 0.8 * math.sin(0.35)
    bearing = math.atan2(y - pose.t[1], x - pose.t[0])
    cylinder = FeatureSettings(model="cylinder")
    for points in (
        _box_points((0.06, 0.06, 0.07), x, y, bearing + math.pi / 4),
        _box_points((0.06, 0.06, 0.07), x, y, bearing),
        _cylinder_points(0.07, 0.05, x, y),
    ):
        bbox, area = _outline(cam, pose, points), _area(cam, pose, points)
        exp = sensory_experience(bbox, FLAT, cam, pose, pixels=area)
        assert exp == sensory_experience(bbox, FLAT, cam, pose, cylinder)
    cone = _frustum_points(0.08, 0.1, 0.0, x, y)
    bbox, area = _outline(cam, pose, cone), _area(cam, pose, cone)
    fitted = sensory_experience(bbox, FLAT, cam, pose, pixels=area)
    assert fitted.height == pytest.approx(0.1, rel=0.03)
    for unusable in (None, 0, bbox[2] * bbox[3] + 1):
        exp = sensory_experience(bbox, FLAT, cam, pose, pixels=unusable)
        assert exp == sensory_experience(bbox, FLAT, cam, pose, cylinder) != fitted


def _lattice(cam: CameraModel, pose: CameraPose, points: np.ndarray) -> tuple[tuple, int] | None:
    """The whole-pixel box (as :func:`_pixels`) and the number of pixel centres inside the
    points' image (their convex hull), as a segmentation gives them."""
    import cv2

    bbox = _pixels(cam, pose, points)
    if bbox is None:
        return None
    hull = cv2.convexHull(cam.project((points - pose.t) @ pose.R).astype(np.float32))
    left, top, w, h = bbox
    inside = sum(
        cv2.pointPolygonTest(hull, (float(u), float(v)), False) >= 0
        for u in range(left, left + w)
        for v in range(top, top + h)
    )
    return bbox, inside


def test_solid_model_takes_small_rasterised_balls_for_balls(op3) -> None:
    """Balls of 64-400 pixels with the box and count of the pixel centres they cover: the box's
    rounding moves the diameter the box alone fits by up to a pixel and the count of that ball by
    several per cent, which the chi-square test weighs; a face-on block of the same size, whose
    count no ball explains, is not taken for one."""
    tree, cam = op3
    rng = np.random.default_rng(3)
    heights, far_off = [], []
    while len(heights) < 30:
        pose = tree.camera_pose(
            {"head_pan": rng.uniform(-0.5, 0.5), "head_tilt": rng.uniform(-0.8, -0.4)}
        )
        distance, bearing = rng.uniform(0.5, 1.8), rng.uniform(-0.6, 0.6)
        x, y = distance * math.cos(bearing), distance * math.sin(bearing)
        d = rng.uniform(0.04, 0.08)
        seen = _lattice(cam, pose, _ball_points(d, x, y))
        if seen is None or not MIN_COUNT <= seen[1] <= 400:
            continue
        exp = sensory_experience(*seen[:1], FLAT, cam, pose, pixels=seen[1])
        heights.append(abs(exp.height / d - 1))
        yaw = math.atan2(y - pose.t[1], x - pose.t[0])
        block = _lattice(cam, pose, _box_points((d, d, d), x, y, yaw))
        if block is not None:
            edges = bbox_edge_pixels(block[0])
            fit = fit_ball(
                cam, pose, (edges[1, 0], edges[2, 0], edges[3, 1], edges[0, 1]), block[1], (x, y, d)
            )
            far_off.append(fit is None or fit[1] > BALL_CHI2)
    assert max(heights) < 0.08
    assert np.median(heights) < 0.03
    assert np.mean(far_off) > 0.9


def test_object_taller_than_the_camera(op3) -> None:
    tree, cam = op3
    pose = tree.camera_pose({"head_tilt": 0.3})  # looking up at a tall box
    tall = _cylinder_points(0.2, 0.7, pose.t[0] + 1.5, pose.t[1] + 0.3)
    exp = sensory_experience(_outline(cam, pose, tall), FLAT, cam, pose)
    assert exp.height == pytest.approx(0.7, rel=0.01)
    assert exp.width == pytest.approx(0.2, rel=0.02)


def test_random_objects_within_the_targets(op3) -> None:
    """Blocks and cylinders 0.3-2 m away, head moving, pixel-exact boxes: median ground-position
    error < 2 % of distance, width and height error < 10 %."""
    tree, cam = op3
    rng = np.random.default_rng(7)
    position, width, height = [], [], []
    while len(position) < 300:
        pose = tree.camera_pose({"head_pan": rng.uniform(-1, 1), "head_tilt": rng.uniform(-1, 0)})
        distance, bearing = rng.uniform(0.3, 2.0), rng.uniform(-1.5, 1.5)
        x, y = distance * math.cos(bearing), distance * math.sin(bearing)
        if rng.random() < 0.5:
            side = rng.uniform(0.04, 0.12)
            size = (side, side, side * rng.uniform(0.8, 1.2))
            yaw = math.atan2(y - pose.t[1], x - pose.t[0])  # blocks face the robot
            points, across = _box_points(size, x, y, yaw), side
        else:
            d, h = rng.uniform(0.04, 0.1), rng.uniform(0.04, 0.15)
            size, points, across = (d, d, h), _cylinder_points(d, h, x, y), d
        bbox = _pixels(cam, pose, points)
        if bbox is None or min(bbox[2:]) < 3:
            continue
        exp = sensory_experience(bbox, FLAT, cam, pose)
        assert exp.on_ground
        seen_from = math.hypot(x - pose.t[0], y - pose.t[1])
        position.append(math.hypot(exp.x - x, exp.y - y) / seen_from)
        width.append(abs(exp.width / across - 1))
        height.append(abs(exp.height / size[2] - 1))
    assert np.median(position) < 0.02
    assert np.median(width) < 0.10
    assert np.median(height) < 0.10


def test_above_the_horizon_keeps_colour_and_has_no_position(op3) -> None:
    tree, cam = op3
    pose = tree.camera_pose({"head_tilt": 0.4})
    hist = np.zeros((3, 16))
    hist[0, 15], hist[1, 4], hist[2, 8] = 1.0, 1.0, 1.0
    exp = sensory_experience((100, 5, 30, 20), hist, cam, pose)
    assert not exp.on_ground
    assert (exp.x, exp.y, exp.width, exp.height) == (None, None, None, None)
    assert (exp.luminance, exp.green_red, exp.yellow_blue) == (248.0, 72.0, 136.0)
    json.dumps(exp.features())  # None -> null, never NaN
    assert FeatureScaling(DEFAULT_STATS).scale(exp)["x"] is None
    with pytest.raises(ValueError):
        SensoryExperience(1.0, 2.0, None, None, 1.0, 1.0, 1.0, on_ground=True)


def test_scaling_maps_two_sigmas_to_the_unit_interval() -> None:
    s = FeatureStats(mean=1.0, sigma=0.25)
    assert (s.scale(0.5), s.scale(1.0), s.scale(1.5)) == (0.0, 0.5, 1.0)
    assert (s.scale(-3.0), s.scale(7.0), s.scale(1.25)) == (0.0, 1.0, 0.75)
    with pytest.raises(ValueError):
        FeatureStats(mean=1.0, sigma=0.0)


def test_scaling_file_settings_and_round_trip(tmp_path: Path) -> None:
    stats = {
        name: FeatureStats(mean=i + 1.0, sigma=0.5 + i, n=10) for i, name in enumerate(FEATURES)
    }
    FeatureScaling(stats).save(tmp_path / "s.toml", "a comment")
    loaded = FeatureScaling.load(tmp_path / "s.toml")
    assert loaded.stats == stats
    inline = {"width": FeatureStats(mean=0.2, sigma=0.1)}
    merged = FeatureScaling.from_settings(
        ScalingSettings(file=tmp_path / "s.toml", features=inline)
    )
    assert merged.stats["width"] == inline["width"] and merged.stats["x"] == stats["x"]
    assert FeatureScaling.from_settings(ScalingSettings()).stats == DEFAULT_STATS
    with pytest.raises(ValueError, match="unknown feature"):
        ScalingSettings(features={"colour": FeatureStats(0.0, 1.0)})
    (tmp_path / "bad.toml").write_text("[x]\nmean = 1.0\n", encoding="utf-8")
    with pytest.raises(ValueError, match="x: needs numbers mean and sigma"):
        FeatureScaling.load(tmp_path / "bad.toml")


def test_stats_command_over_json_lines(tmp_path: Path) -> None:
    rng = np.random.default_rng(8)
    rows = [
        {name: float(v) for name, v in zip(FEATURES, rng.normal(size=7), strict=True)}
        for _ in range(40)
    ]
    lines = []
    for i in range(0, 40, 4):  # world messages of two objects, single objects, flat dicts
        objects = [{"id": f"o{i}", "features": rows[i]}, {"features": rows[i + 1]}]
        lines.append(json.dumps({"schema": "percept.world/1", "objects": objects}))
        lines.append(json.dumps({"payload": {"features": rows[i + 2]}}))
        lines.append(json.dumps(rows[i + 3]))
    off = dict.fromkeys(FEATURES[:4]) | {"luminance": 7.0, "green_red": 7.0, "yellow_blue": 7.0}
    lines.append(json.dumps({"objects": [{"features": off, "on_ground": False}]}))
    (tmp_path / "run.jsonl").write_text("\n".join(lines) + "\n", encoding="utf-8")
    out = tmp_path / "stats.toml"
    assert main(["stats", str(tmp_path / "run.jsonl"), "--out", str(out)]) == 0
    stats = FeatureScaling.load(out).stats
    x = [r["x"] for r in rows]
    assert stats["x"].mean == pytest.approx(np.mean(x)) and stats["x"].n == 40
    assert stats["x"].sigma == pytest.approx(np.std(x, ddof=1))
    lum = [r["luminance"] for r in rows] + [7.0]
    assert stats["luminance"].mean == pytest.approx(np.mean(lum)) and stats["luminance"].n == 41


def test_stats_command_refuses_too_little_data(tmp_path: Path, capsys) -> None:
    (tmp_path / "one.jsonl").write_text(json.dumps({"x": 1.0}) + "\n", encoding="utf-8")
    assert main(["stats", str(tmp_path / "one.jsonl"), "--out", str(tmp_path / "o.toml")]) == 1
    assert "need at least two" in capsys.readouterr().err


class _View(NamedTuple):
    """One object in one simulated camera image, with its truth in the robot's ground frame."""

    robot: str
    t: float
    oid: int
    shape: str
    centre: np.ndarray
    """The footprint's centre."""
    across: float
    """The footprint's extent across the line of sight."""
    top: float
    experiences: dict[str, SensoryExperience]
    """By feature model."""
    world_xy: dict[str, np.ndarray]
    """The models' positions in the world frame."""


def _simulated_views(shapes: list[tuple[str, tuple[float, float, float], tuple[float, float]]]):
    """Two OP3s with moving heads look at ``shapes`` (shape, size, place) 0.3-2 m away in the
    simulated world (MuJoCo): features, with every model, from each object's true bounding box,
    pixel count and its pixels' histograms, the camera pose from percept's forward kinematics."""
    import cv2

    from percept.drivers.sim.scene import JointMotion, Scene, SimObject, SimRobot
    from percept.drivers.sim.world import SimWorld

    moving = {
        "head_pan": JointMotion(amplitude=0.5, period=6.0),
        "head_tilt": JointMotion(offset=-0.55, amplitude=0.2, period=4.0),
    }
    robots = (
        SimRobot(name="a", profile=OP3, pose=(-1.0, 0.0, 0.0), joints=moving),
        SimRobot(name="b", profile=OP3, pose=(0.3, -0.9, 1.9), joints=moving),
    )
    objects = tuple(
        SimObject(id=i + 1, shape=s, size=size, color=(200, 40 * i, 60), pose=(*xy, 0.4 * i))
        for i, (s, size, xy) in enumerate(shapes)
    )
    scene = Scene(name="features", robots=robots, objects=objects)
    profile = load_profile(OP3)
    tree = KinematicTree.from_settings(profile.kinematics)
    models = ("solid", "cylinder", "chapter")
    with SimWorld(scene, {"a": profile, "b": profile}) as world:
        for t in np.arange(0.0, 6.0, 0.5):
            truth = world.truth(float(t))
            for name in ("a", "b"):
                cam, me = world.camera_model(name), truth.robots[name]
                pose = tree.camera_pose(me.joints)
                assert np.abs(pose.t - me.camera.t).max() < 1e-6
                ycrcb = cv2.cvtColor(
                    world.render(name, float(t), effects=False), cv2.COLOR_BGR2YCrCb
                )
                labels = world.labels(name, float(t))
                yaw = me.pose[2]
                to_me = np.array([[math.cos(yaw), math.sin(yaw)], [-math.sin(yaw), math.cos(yaw)]])
                for oid, view in truth.views[name].objects.items():
                    b = view.bbox
                    if b is None or view.visible < 0.98 or view.pixels < 30:
                        continue
                    if min(b[:2]) == 0 or b[0] + b[2] >= cam.width or b[1] + b[3] >= cam.height:
                        continue
                    mask = (labels == oid).astype(np.uint8)
                    hist = np.vstack(
                        [cv2.calcHist([ycrcb], [c], mask, [16], [0, 256]).ravel() for c in range(3)]
                    )
                    hist /= hist.sum(1, keepdims=True)
                    experiences = {
                        model: sensory_experience(
                            b, hist, cam, pose, FeatureSettings(model=model), pixels=view.pixels
                        )
                        for model in models
                    }
                    obj = truth.objects[oid]
                    centre = to_me @ (obj.position[:2] - me.pose[:2])
                    sight = (centre - pose.t[:2]) / np.linalg.norm(centre - pose.t[:2])
                    corners = np.array(
                        [
                            [a * obj.size[0], c * obj.size[1]]
                            for a in (-0.5, 0.5)
                            for c in (-0.5, 0.5)
                        ]
                    )
                    footprint = corners @ (to_me @ obj.R[:2, :2]).T
                    across = float(np.ptp(footprint @ [-sight[1], sight[0]]))
                    if obj.shape in ("cylinder", "cone", "ball"):
                        across = obj.size[0]
                    world_xy = {
                        m: to_me.T @ [e.x, e.y] + me.pose[:2] for m, e in experiences.items()
                    }
                    yield _View(
                        name,
                        float(t),
                        oid,
                        obj.shape,
                        centre,
                        across,
                        obj.top,
                        experiences,
                        world_xy,
                    )


def _errors(views: list[_View], model: str) -> dict[str, np.ndarray]:
    """|relative error| per view of a model's position (to the distance), width and height."""
    out: dict[str, list[float]] = {"position": [], "width": [], "height": []}
    for v in views:
        e = v.experiences[model]
        out["position"].append(
            math.hypot(e.x - v.centre[0], e.y - v.centre[1]) / np.linalg.norm(v.centre)
        )
        out["width"].append(abs(e.width / v.across - 1))
        out["height"].append(abs(e.height / v.top - 1))
    return {k: np.array(x) for k, x in out.items()}


@pytest.mark.timeout(120)
def test_simulated_objects_match_the_truth() -> None:
    """Six flat-topped objects (blocks, cuboids, cylinders) seen by two moving robots in the
    simulated world: position, width and height within the targets with the default model, and
    the same object seen by both robots at once in the same place, size and colour."""
    views = list(
        _simulated_views(
            [
                ("block", (0.06, 0.06, 0.08), (0.1, 0.2)),
                ("cuboid", (0.12, 0.05, 0.06), (-0.3, -0.1)),
                ("cylinder", (0.07, 0.07, 0.1), (0.3, -0.2)),
                ("block", (0.04, 0.04, 0.04), (-0.1, -0.4)),
                ("cylinder", (0.05, 0.05, 0.12), (0.0, 0.45)),
                ("cuboid", (0.08, 0.08, 0.05), (0.45, 0.25)),
            ]
        )
    )
    assert len(views) > 40
    errors = _errors(views, FeatureSettings().model)
    assert np.median(errors["position"]) < 0.02
    assert np.median(errors["width"]) < 0.10
    assert np.median(errors["height"]) < 0.10
    seen: dict[tuple[float, int], dict[str, _View]] = {}
    for v in views:
        seen.setdefault((v.t, v.oid), {})[v.robot] = v
    both = [pair for pair in seen.values() if len(pair) == 2]
    assert len(both) > 5
    model = FeatureSettings().model
    apart = [np.linalg.norm(p["a"].world_xy[model] - p["b"].world_xy[model]) for p in both]
    assert np.median(apart) < 0.02
    lum = [
        abs(p["a"].experiences[model].luminance - p["b"].experiences[model].luminance) for p in both
    ]
    assert np.median(lum) < 20


@pytest.mark.timeout(120)
def test_simulated_round_topped_objects_with_the_solid_model() -> None:
    """Cones, balls and toys, which the cylinder model reads 15-30 % too low: the solid model's
    heights are within the 10 % target (and its positions better)."""
    views = list(
        _simulated_views(
            [
                ("cone", (0.08, 0.08, 0.1), (0.1, 0.2)),
                ("ball", (0.07, 0.07, 0.07), (-0.3, -0.1)),
                ("toy", (0.06, 0.07, 0.1), (0.3, -0.2)),
                ("ball", (0.05, 0.05, 0.05), (-0.1, -0.4)),
                ("cone", (0.06, 0.06, 0.08), (0.0, 0.45)),
                ("ball", (0.09, 0.09, 0.09), (0.45, 0.25)),
            ]
        )
    )
    assert len(views) > 40
    solid, cylinder = _errors(views, "solid"), _errors(views, "cylinder")
    assert np.median(solid["height"]) < 0.10 < np.median(cylinder["height"])
    assert np.median(solid["position"]) < np.median(cylinder["position"])
    assert np.median(solid["width"]) < 0.10
    balls = [v for v in views if v.shape == "ball"]
    assert np.median(_errors(balls, "solid")["height"]) < 0.05


def test_stats_command_over_an_mcap_recording(tmp_path: Path) -> None:
    from mcap.writer import Writer

    rng = np.random.default_rng(9)
    widths = rng.uniform(0.02, 0.2, 30)
    path = tmp_path / "run.mcap"
    with path.open("wb") as fh:
        writer = Writer(fh)
        writer.start()
        world = writer.register_channel("/percept/world", "json", 0)
        image = writer.register_channel("/camera/image", "cdr", 0)
        for i, w in enumerate(widths):
            features = dict.fromkeys(FEATURES, float(i)) | {"width": float(w)}
            message = {"schema": "percept.world/1", "objects": [{"features": features}]}
            writer.add_message(world, i, json.dumps(message).encode(), i)
            writer.add_message(image, i, b"\x00\x01 not json", i)
        writer.finish()
    out = tmp_path / "stats.toml"
    assert main(["stats", str(path), "--out", str(out)]) == 0
    stats = FeatureScaling.load(out).stats
    assert stats["width"].mean == pytest.approx(widths.mean()) and stats["width"].n == 30
    assert stats["x"].mean == pytest.approx(14.5)
