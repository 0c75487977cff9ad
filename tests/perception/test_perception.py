"""The perception core on synthetic scenes drawn with OpenCV: anchors, splitting, motion gating,
deletion, histograms, bad frames, robust calibration, and the exactness of the fast paths."""

from __future__ import annotations

import logging
from dataclasses import FrozenInstanceError, fields, replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from percept.config.loader import load
from percept.perception.colour import Coding, to_ycrcb
from percept.perception.evaluation.synthetic import Blob, SyntheticScene, busy_scene
from percept.perception.evaluation.tracking import iou
from percept.perception.params import BackgroundParams, PerceptionParams
from percept.perception.pipeline import FrameResult, Perception
from percept.perception.segmentation.background import BackgroundModel, CalibrationError
from percept.perception.segmentation.labelling.regions import find_regions, grid_step, subsample
from percept.perception.tracking.anchors import Anchor
from percept.perception.tracking.kalman import BoxFilters
from percept.perception.tracking.motion import MotionDetector

pytestmark = pytest.mark.timeout(60)

MARGINALS = Coding(16, joint=False)

REPO = Path(__file__).resolve().parents[2]
W, H = 176, 144
FPS = 25.0
RED, GREEN, BLUE, YELLOW = (40, 40, 220), (40, 190, 40), (220, 60, 40), (30, 210, 230)


def still(colour, x, y, start=0, stop=200, size=(0.12, 0.15), hidden=()):
    return Blob(colour, size, ((start, x, y), (stop, x, y)), hidden=hidden)


def run(scene: SyntheticScene, frames: int, params: PerceptionParams | None = None):
    """Calibrate on the empty scene, then process ``frames`` frames; results per frame."""
    perception = Perception(params or PerceptionParams(), scene.width, scene.height)
    perception.calibrate(scene.empty(30))
    return [perception.process(scene.render(f), f / FPS) for f in range(frames)]


def visible(result: FrameResult) -> list[Anchor]:
    return [a for a in result.anchors if a.visible]


def best_match(result: FrameResult, box) -> tuple[Anchor | None, float]:
    """The visible anchor overlapping ``box`` most, and that IoU."""
    anchors = visible(result)
    if not anchors:
        return None, 0.0
    overlaps = iou(np.array([box], float), np.array([a.bbox for a in anchors]))[0]
    i = int(np.argmax(overlaps))
    return anchors[i], float(overlaps[i])


def ids_of(results: list[FrameResult], scene: SyntheticScene, blob: int, frames) -> set[str]:
    """Ids of the anchors that matched blob ``blob`` (IoU >= 0.5) over ``frames``."""
    out = set()
    for f in frames:
        box = scene.box(scene.blobs[blob], f)
        anchor, overlap = best_match(results[f], box)
        assert anchor is not None and overlap >= 0.5, f"frame {f}: blob {blob} not tracked"
        out.add(anchor.id)
    return out


def test_new_object_gets_an_anchor() -> None:
    scene = SyntheticScene(W, H, [still(RED, 0.5, 0.5, start=5)])
    results = run(scene, 15)
    assert all(not r.anchors for r in results[:5])
    assert ids_of(results, scene, 0, range(7, 15)) == {"o1"}
    assert len(results[-1].anchors) == 1


def test_anchor_snapshots_are_the_frozen_records_of_their_fields() -> None:
    scene = SyntheticScene(W, H, [still(RED, 0.3, 0.5, start=2), still(GREEN, 0.7, 0.5, start=2)])
    anchors = run(scene, 8)[-1].anchors
    assert len(anchors) == 2
    for anchor in anchors:
        values = {f.name: getattr(anchor, f.name) for f in fields(Anchor)}
        assert vars(anchor).keys() == values.keys()
        made = Anchor(**values)
        assert all(getattr(made, name) is value for name, value in values.items())
        assert anchor.visible and anchor.age == made.age
        with pytest.raises(FrozenInstanceError):
            anchor.pixels = 0  # type: ignore[misc]


def test_keeps_its_id_while_moving() -> None:
    keys = ((0, 0.2, 0.5), (10, 0.2, 0.5), (50, 0.8, 0.6), (60, 0.8, 0.6))
    scene = SyntheticScene(W, H, [Blob(RED, (0.12, 0.15), keys)])
    results = run(scene, 60)
    assert ids_of(results, scene, 0, range(2, 60)) == {"o1"}
    assert any(a.in_motion for r in results[15:45] for a in r.anchors)
    assert results[30].anchors[0].velocity[0] > 0.5  # moving right, pixels per frame


def test_keeps_its_id_under_partial_occlusion() -> None:
    crossing = Blob(BLUE, (0.12, 0.15), ((0, 0.2, 0.45), (8, 0.2, 0.45), (60, 0.8, 0.45)))
    scene = SyntheticScene(W, H, [still(RED, 0.5, 0.5, size=(0.16, 0.2)), crossing])
    results = run(scene, 60)
    # The blue box covers up to about half of the red one around frame 34.
    red, blue = ids_of(results, scene, 0, range(2, 60)), ids_of(results, scene, 1, range(2, 60))
    assert len(red) == len(blue) == 1 and red != blue


def test_keeps_its_id_after_a_short_disappearance() -> None:
    scene = SyntheticScene(W, H, [still(GREEN, 0.4, 0.4, hidden=((20, 30),))])
    results = run(scene, 45)
    assert all(not visible(r) for r in results[20:30])
    assert all(len(r.anchors) == 1 for r in results[20:30])  # kept, not seen
    assert ids_of(results, scene, 0, list(range(2, 20)) + list(range(32, 45))) == {"o1"}


def test_anchor_deleted_after_the_absence_time() -> None:
    params = PerceptionParams()
    absence = params.anchors.max_absence
    last = 10
    scene = SyntheticScene(W, H, [still(YELLOW, 0.5, 0.5, stop=last)])
    results = run(scene, last + int(absence * FPS) + 5)
    for f, r in enumerate(results[last + 1 :], start=last + 1):
        gone = f / FPS - last / FPS > absence
        assert (len(r.anchors) == 0) == gone, f"frame {f}"


def with_colour_model(model: str) -> PerceptionParams:
    defaults = PerceptionParams()
    return replace(defaults, regions=replace(defaults.regions, colour_model=model))


@pytest.mark.parametrize("model", ["marginals", "joint_chroma"])
def test_touching_objects_become_two_percepts_once_both_have_models(model) -> None:
    mover = Blob(
        GREEN, (0.12, 0.15), ((0, 0.2, 0.5), (5, 0.2, 0.5), (25, 0.41, 0.5), (60, 0.41, 0.5))
    )
    scene = SyntheticScene(W, H, [still(RED, 0.52, 0.5), mover])
    assert scene.box(scene.blobs[0], 40)[0] <= sum(scene.box(scene.blobs[1], 40)[::2])  # touch
    results = run(scene, 45, with_colour_model(model))
    after = results[40]
    assert len(after.masks.regions) == 1  # one foreground region holds both objects
    assert len(after.percepts) == 2
    red, green = ids_of(results, scene, 0, range(2, 45)), ids_of(results, scene, 1, range(2, 45))
    assert len(red) == len(green) == 1 and red != green
    # Without the colour split the same region is one percept, and tracking suffers.
    unsplit = run(
        scene,
        45,
        replace(with_colour_model(model), split=replace(PerceptionParams().split, enabled=False)),
    )
    assert len(unsplit[40].percepts) == 1


def test_no_anchor_is_created_inside_a_moving_region() -> None:
    keys = ((5, 0.1, 0.5), (30, 0.9, 0.5), (40, 0.9, 0.5))  # enters moving, then stops
    scene = SyntheticScene(W, H, [Blob(BLUE, (0.12, 0.15), keys)])
    results = run(scene, 40)
    assert all(not r.anchors for r in results[:31])
    assert all(r.percepts for r in results[5:31])  # it was seen, just not anchored
    assert results[-1].anchors and results[-1].anchors[0].created > 30 / FPS


@pytest.mark.parametrize(("model", "shape"), [("marginals", (3, 16)), ("joint_chroma", (2, 256))])
def test_histograms_stay_normalised(model, shape) -> None:
    scene = busy_scene(W, H, 80)
    for r in run(scene, 80, with_colour_model(model)):
        for h in [a.histograms for a in r.anchors] + [p.histograms for p in r.percepts]:
            assert h.shape == shape
            assert np.all(h >= 0)
            np.testing.assert_allclose(h.sum(axis=1), 1.0, atol=1e-9)


@pytest.mark.parametrize(
    "bad",
    [
        None,
        np.zeros((0, 0, 3), np.uint8),
        np.zeros((H, W), np.uint8),
        np.zeros((H, W, 3), float),
        np.zeros((H + 1, W, 3), np.uint8),
        "frame",
    ],
    ids=["none", "empty", "grey", "float", "size", "str"],
)
def test_a_corrupt_or_empty_frame_is_skipped_with_a_logged_error(bad, caplog) -> None:
    scene = SyntheticScene(W, H, [still(RED, 0.5, 0.5)])
    perception = Perception(PerceptionParams(), W, H)
    perception.calibrate(scene.empty(10))
    before = [perception.process(scene.render(f), f / FPS) for f in range(5)][-1]
    with caplog.at_level(logging.ERROR, logger="percept.perception"):
        result = perception.process(bad, 5 / FPS)
    assert result.skipped and result.masks is None and result.percepts == []
    assert [a.id for a in result.anchors] == [a.id for a in before.anchors] == ["o1"]
    assert any("skipped" in r.getMessage() for r in caplog.records)
    after = perception.process(scene.render(6), 6 / FPS)
    assert not after.skipped and [a.id for a in visible(after)] == ["o1"]


def test_calibration_tolerates_an_object_passing_through() -> None:
    passer = Blob(RED, (0.15, 0.3), ((0, -0.1, 0.5), (30, 1.1, 0.5)))
    scene = SyntheticScene(W, H, [passer])
    frames = [scene.render(f) for f in range(30)]  # every column is covered in ~5 of 30 frames
    truth = to_ycrcb(scene.background).astype(float)
    robust = BackgroundModel.calibrate(frames, BackgroundParams())
    plain = BackgroundModel.calibrate(frames, replace(BackgroundParams(), estimator="mean"))
    path = np.s_[int(0.4 * H) : int(0.6 * H), :]
    assert np.abs(robust.mean - truth).max() < 4.0
    assert np.median(robust.sigma[path]) < 3.0
    # The control: the chapter's plain mean and deviation keep a ghost and go blind there.
    assert np.abs(plain.mean - truth).max() > 10.0
    assert np.median(plain.sigma[path]) > 10.0
    assert np.count_nonzero(robust.apply(scene.empty(1)[0])) < 0.002 * W * H
    probe = SyntheticScene(W, H, [still(GREEN, 0.5, 0.5, size=(0.3, 0.25))])
    left, top, w, h = probe.box(probe.blobs[0], 1)
    found = robust.apply(probe.render(1))[top : top + h, left : left + w] > 0
    assert found.mean() > 0.99


def test_background_progress_and_save_load(tmp_path) -> None:
    scene = SyntheticScene(W, H, [])
    seen = []
    model = BackgroundModel.calibrate(
        scene.empty(12),
        replace(BackgroundParams(), calibration_frames=10),
        lambda d, n: seen.append((d, n)),
    )
    assert seen == [(i, 10) for i in range(1, 11)]
    model.save(tmp_path / "bg.npz")
    again = BackgroundModel.load(tmp_path / "bg.npz", BackgroundParams())
    image = SyntheticScene(W, H, [still(RED, 0.5, 0.5)]).render(3)
    np.testing.assert_array_equal(model.apply(image), again.apply(image))


def test_integer_bounds_give_the_literal_test() -> None:
    rng = np.random.default_rng(1)
    mean = rng.uniform(0, 255, (40, 50, 3)).astype(np.float32)
    sigma = rng.uniform(0, 6, (40, 50, 3)).astype(np.float32)
    params = replace(BackgroundParams(), k=1.7, sigma_min=1.3)
    model = BackgroundModel(mean, sigma, params)
    for _ in range(5):
        ycc = np.clip(mean + rng.normal(0, 6, mean.shape), 0, 255).astype(np.uint8)
        literal = np.any(
            np.abs(ycc - mean) > params.k * np.maximum(sigma, params.sigma_min), axis=2
        )
        np.testing.assert_array_equal(model.classify(ycc).astype(bool), literal)


@pytest.mark.parametrize("size", [(W, H), (640, 480)])
def test_motion_in_boxes_equals_the_whole_mask(size) -> None:
    w, h = size
    scene = busy_scene(w, h, 40)
    model = BackgroundModel.calibrate(scene.empty(5), BackgroundParams())
    detector = MotionDetector(model, 4.0, 3)
    detector.update(to_ycrcb(scene.render(9)))
    motion = detector.update(to_ycrcb(scene.render(10)))
    boxes = np.array(
        [[0, 0, w, h], [10.5, 5, w / 4, h / 5], [-5, -5, w / 5, h / 5], [w - 20, h - 20, 40, 40]]
    )
    fractions = motion.fraction(boxes)  # before the whole mask exists: from the frames
    full = motion.mask()
    assert full.any()
    for box, fraction in zip(boxes, fractions, strict=True):
        x0, y0 = max(int(box[0]), 0), max(int(box[1]), 0)
        x1, y1 = min(int(np.ceil(box[0] + box[2])), w), min(int(np.ceil(box[1] + box[3])), h)
        assert fraction == pytest.approx(full[y0:y1, x0:x1].mean())
    many = np.repeat(boxes, 10, axis=0)  # now counted on the whole mask
    np.testing.assert_allclose(motion.fraction(many), np.repeat(fractions, 10))


def test_regions_match_opencv_statistics() -> None:
    scene = busy_scene(W, H, 40)
    image = scene.render(12, noise=False)
    mask = (np.abs(image.astype(int) - scene.background.astype(int)).max(axis=2) > 0).astype(
        np.uint8
    )
    ycc = to_ycrcb(image)
    regions = find_regions(mask, ycc, MARGINALS, 5)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    expected = sorted(tuple(s[:5]) for s in stats[1:] if s[4] >= 5)
    got = sorted(
        (*b, c) for b, c in zip(regions.boxes.tolist(), regions.counts.tolist(), strict=True)
    )
    assert got == expected
    for i in range(len(regions)):
        inside = labels == regions.label_ids[i]
        for c in range(3):
            hist = np.bincount(ycc[..., c][inside] // 16, minlength=16) / inside.sum()
            np.testing.assert_allclose(regions.histograms[i, c], hist)
        outline = regions.outline(i)
        x, y, w, h = cv2.boundingRect(outline)
        assert (x, y, w, h) == tuple(regions.boxes[i])


def test_batched_kalman_equals_filterpy() -> None:
    rng = np.random.default_rng(3)
    q, r, p0, v0 = 0.03, 2.0, 4.0, 1.5
    bank = BoxFilters(q, r, p0, v0)
    starts = rng.uniform(10, 100, (3, 4))
    bank.add(starts)
    reference = []
    for z in starts:
        kf = KalmanFilter(dim_x=8, dim_z=4)
        kf.F = bank.A.copy()
        kf.H = np.eye(4, 8)
        kf.Q, kf.R = q * np.eye(8), r * np.eye(4)
        kf.P = np.diag([p0] * 4 + [v0] * 4)
        kf.x = np.concatenate([z, np.zeros(4)])[:, None]
        reference.append(kf)
    for _ in range(30):
        bank.predict()
        for kf in reference:
            kf.predict()
        rows = np.flatnonzero(rng.random(3) < 0.7)
        z = rng.uniform(10, 100, (len(rows), 4))
        bank.update(rows, z)
        for row, measurement in zip(rows, z, strict=True):
            reference[row].update(measurement)
    for i, kf in enumerate(reference):
        np.testing.assert_allclose(bank.x[i], kf.x[:, 0], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(bank.P[i], kf.P, rtol=1e-9, atol=1e-9)


def test_chapter_preset_loads_and_runs() -> None:
    params = load(PerceptionParams, REPO / "config" / "presets" / "perception-chapter.toml")
    assert (params.background.k, params.motion.k) == (1.0, 1.0)
    assert (params.anchors.q, params.anchors.r) == (1e-5, 0.1)
    assert params.background.estimator == "mean" and params.regions.opening == 3
    scene = SyntheticScene(W, H, [still(RED, 0.5, 0.5, start=3)])
    results = run(scene, 8, params)
    assert all(not r.skipped for r in results)


@pytest.mark.parametrize(("width", "height", "step"), [(640, 480, 2), (641, 479, 2), (90, 60, 3)])
def test_subsample_is_every_step_th_pixel(width, height, step) -> None:
    image = np.random.default_rng(1).integers(0, 256, (height, width, 3), dtype=np.uint8)
    grid = subsample(image, step)
    np.testing.assert_array_equal(grid, image[::step, ::step])
    assert grid.flags.c_contiguous
    grey = image[..., 1]  # one channel, a view that is not contiguous
    np.testing.assert_array_equal(subsample(grey, step), grey[::step, ::step])
    assert grid_step(640, 480, 320 * 240) == 2 and grid_step(176, 144, 320 * 240) == 1
    assert grid_step(1280, 720, 320 * 240) == 4 and grid_step(1280, 720, 0) == 1


def _found_alike(
    scene: SyntheticScene, fine: list[FrameResult], coarse: list[FrameResult], pixels: float
) -> None:
    """Both runs find every blob of ``scene`` in frames 30, 45 and 59 (boxes overlapping 0.7),
    with boxes within ``pixels`` of each other."""
    for f in (30, 45, 59):
        for blob in scene.blobs:
            box = scene.box(blob, f)
            a, overlap_a = best_match(fine[f], box)
            b, overlap_b = best_match(coarse[f], box)
            assert overlap_a >= 0.7 and overlap_b >= 0.7
            assert np.abs(np.subtract(a.bbox, b.bbox)).max() <= pixels


def test_the_grid_tracks_like_every_pixel() -> None:
    """At 640x480 the default grid (every 2nd pixel) finds the same objects as every pixel,
    with boxes within two pixels, and its masks come back at the image's size."""
    scene = busy_scene(640, 480, 60)
    every = replace(PerceptionParams(), regions=replace(PerceptionParams().regions, grid_pixels=0))
    fine, coarse = run(scene, 60, every), run(scene, 60)
    assert Perception(PerceptionParams(), 640, 480).step == 2
    _found_alike(scene, fine, coarse, 2.0)
    masks = coarse[59].masks
    assert masks.foreground.shape == masks.motion.shape == masks.classes.shape == (480, 640)
    agree = (masks.foreground > 0) == (fine[59].masks.foreground > 0)
    assert agree.mean() > 0.99


def test_ycrcb_is_opencvs_to_one_grey_level() -> None:
    """Every 8-bit colour (a 4096x4096 image of all 2^24) against ``cv2.cvtColor``."""
    levels = np.arange(256, dtype=np.uint8)
    every = np.stack(np.meshgrid(levels, levels, levels, indexing="ij"), axis=-1)
    image = every.reshape(4096, 4096, 3)
    difference = cv2.absdiff(to_ycrcb(image), cv2.cvtColor(image, cv2.COLOR_BGR2YCrCb))
    assert difference.max() == 1
    assert (difference > 0).mean() < 0.2


def _jpeg(image: np.ndarray) -> np.ndarray:
    return cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])[1]


def test_grid_frames_track_like_full_frames() -> None:
    """JPEG frames decoded at half size (the grid of 640x480) and calibrated on as such find
    the same objects as the full decode, boxes within one and a half grid pixels (3 px: a block
    half on an object's edge averages to foreground); frames of the other kind are skipped."""
    from percept.perception.segmentation.grid_frame import GridFrame

    scene = busy_scene(640, 480, 60)

    def decoded(images: list[np.ndarray], flags: int) -> list[np.ndarray]:
        return [cv2.imdecode(_jpeg(image), flags) for image in images]

    empty, shown = scene.empty(30), [scene.render(f) for f in range(60)]
    full = Perception(PerceptionParams(), 640, 480)
    full.calibrate(decoded(empty, cv2.IMREAD_COLOR))
    fine = [
        full.process(image, f / FPS) for f, image in enumerate(decoded(shown, cv2.IMREAD_COLOR))
    ]
    grid = Perception(PerceptionParams(), 640, 480)
    reduced = cv2.IMREAD_REDUCED_COLOR_2
    grid.calibrate(GridFrame.of(image, 2) for image in decoded(empty, reduced))
    assert grid.grid_frames and grid.background is not None
    assert grid.background.shape == (240, 320)
    coarse = [
        grid.process(GridFrame.of(image, 2), f / FPS)
        for f, image in enumerate(decoded(shown, reduced))
    ]
    _found_alike(scene, fine, coarse, 3.0)
    assert coarse[59].masks is not None and coarse[59].masks.foreground.shape == (480, 640)
    assert full.process(GridFrame.of(shown[0][::2, ::2], 2), 3.0).skipped
    assert grid.process(shown[0], 3.0).skipped
    assert grid.process(GridFrame.of(shown[0][::4, ::4], 4), 3.0).skipped
    # calibrating on frames of another size (a grid's, given as a full frame) says which
    with pytest.raises(CalibrationError, match=r"calibration frame 1 is \(240, 320, 3\)"):
        Perception(PerceptionParams(), 640, 480).calibrate([shown[0][::2, ::2]])
    with pytest.raises(CalibrationError, match="a grid frame of step 4, expected step 2"):
        Perception(PerceptionParams(), 640, 480).calibrate([GridFrame.of(shown[0][::4, ::4], 4)])


def test_a_grid_background_saved_and_loaded_takes_grid_frames(tmp_path: Path) -> None:
    from percept.perception.segmentation.grid_frame import GridFrame

    scene = busy_scene(640, 480, 40)
    first = Perception(PerceptionParams(), 640, 480)
    first.calibrate(
        GridFrame.of(cv2.resize(e, (320, 240), interpolation=cv2.INTER_AREA), 2)
        for e in scene.empty(20)
    )
    first.save_background(tmp_path / "bg.npz")
    again = Perception(PerceptionParams(), 640, 480)
    again.load_background(tmp_path / "bg.npz")
    assert again.grid_frames
    image = cv2.resize(scene.render(30), (320, 240), interpolation=cv2.INTER_AREA)
    mask = again.foreground(GridFrame.of(image, 2))
    assert mask is not None and mask.shape == (480, 640)
    assert np.array_equal(mask, first.foreground(GridFrame.of(image, 2)))
    assert 0.01 < (mask > 0).mean() < 0.5
