"""The background through a lab session's light (perception/light): photometric compensation,
shadows, sudden changes, ghosts and selective maintenance, on synthetic table-top images run
through the real pipeline (OpenCV, the anchor tracker)."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from percept.kinematics.camera import CameraModel
from percept.perception.colour import to_ycrcb
from percept.perception.evaluation.cubes import GREEN, RED, Cube, head_pose, render
from percept.perception.evaluation.synthetic import Blob, SyntheticScene
from percept.perception.light.foreground import foreground, view_foreground
from percept.perception.light.maintenance import Maintenance
from percept.perception.light.photometry.change import Change, ChangeDetector
from percept.perception.light.photometry.photometric import IDENTITY, Photometry, fit
from percept.perception.params import LightParams, PerceptionParams
from percept.perception.pipeline import FrameResult, Perception
from percept.perception.segmentation.background import BackgroundModel

W, H = 176, 144
FPS = 10.0


def scene(*blobs: Blob, seed: int = 3) -> SyntheticScene:
    return SyntheticScene(W, H, list(blobs), noise=2.0, seed=seed)


def still(colour: tuple[int, int, int], x: float, y: float, size: float = 0.14) -> Blob:
    return Blob(colour, (size, size), ((0, x, y), (100_000, x, y)))


def params(**light: object) -> PerceptionParams:
    base = PerceptionParams()
    return replace(base, light=replace(base.light, **light))


def calibrated(p: PerceptionParams, frames: list[np.ndarray]) -> Perception:
    perception = Perception(p, W, H)
    perception.calibrate(frames)
    return perception


def lit(image: np.ndarray, scale: float | np.ndarray) -> np.ndarray:
    """The image under ``scale`` times the light (a number, or one per pixel (H, W))."""
    s = np.asarray(scale, np.float32)
    if s.ndim == 2:
        s = s[..., None]
    return np.clip(image.astype(np.float32) * s, 0, 255).astype(np.uint8)


def wooden(image: np.ndarray) -> np.ndarray:
    """The synthetic table (nearly grey) tinted like wood: a shadow keeps a tint, and only a
    tint tells a shadow from a grey object."""
    tint = np.array([0.65, 0.9, 1.15], np.float32)  # B, G, R
    return np.clip(image.astype(np.float32) * tint, 0, 255).astype(np.uint8)


def run(perception: Perception, frames: list[np.ndarray], t0: float) -> list[FrameResult]:
    return [perception.process(f, t0 + i / FPS) for i, f in enumerate(frames)]


def test_gain_and_offset_are_recovered_from_a_frame_in_other_light() -> None:
    """Darker light (x 0.7) and a bluer white balance (+12 in B): the fit on all pixels, a
    quarter of them covered by an object, recovers the gain of every channel, and the
    compensated frame matches the calibration within the noise outside the object."""
    s = scene()
    model = to_ycrcb(s.render(0)).astype(np.float32)
    frame = lit(s.render(1), 0.7)
    frame[..., 0] = cv2.add(frame[..., 0], 12)
    frame[: H // 2, : W // 2] = (20, 200, 240)  # an object the fit must leave out
    ycc = to_ycrcb(frame)
    photometry = fit(ycc, model, np.zeros((H, W), bool), np.zeros((H, W), np.uint8))
    assert photometry.gain[0] == pytest.approx(0.7, abs=0.03)
    assert photometry.gain[2] > 0.6  # Cb: scaled like the light, then shifted
    assert photometry.offset[2] > 3.0  # the bluer white balance raises Cb
    back = cv2.transform(ycc, photometry.matrix).astype(np.float32)
    outside = np.ones((H, W), bool)
    outside[: H // 2, : W // 2] = False
    error = np.abs(back - model)[outside]
    assert np.median(error) < 3.0
    assert photometry.inliers < H * W * 0.8  # the object's quarter was trimmed


def test_a_shadow_is_not_foreground_but_an_object_is() -> None:
    s = scene()
    perception = calibrated(params(), [wooden(f) for f in s.empty(20)])
    frame = wooden(s.render(5))
    frame[20:70, 20:80] = lit(frame[20:70, 20:80], 0.55)  # a hand's shadow
    frame[80:120, 110:150] = (30, 40, 200)  # a red object
    fg = perception.process(frame, 0.0).masks.foreground
    assert (fg[25:65, 25:75] > 0).mean() < 0.02
    assert (fg[85:115, 115:145] > 0).mean() > 0.95
    off = calibrated(params(shadows=False), [wooden(f) for f in s.empty(20)])
    assert (off.process(frame, 0.0).masks.foreground[25:65, 25:75] > 0).mean() > 0.9


def test_a_grey_object_on_a_grey_table_is_not_taken_for_a_shadow() -> None:
    """On a grey surface a shadow is grey too, and so is a grey object: the chroma cannot tell
    them apart, so the shadow test leaves such pixels foreground (a dark car on a road, a grey
    barrel on a grey table)."""
    s = scene()
    perception = calibrated(params(), s.empty(20))  # the table's chroma is within a few of grey
    frame = s.render(5)
    rng = np.random.default_rng(5)
    grey = 0.55 * np.median(frame) + rng.normal(0, 2, (40, 40, 1))  # as dark as the shadow above
    frame[80:120, 110:150] = np.clip(grey, 0, 255).astype(np.uint8)
    fg = perception.process(frame, 0.0).masks.foreground
    assert (fg[85:115, 115:145] > 0).mean() > 0.95


def test_a_hands_shadow_held_still_makes_no_anchor() -> None:
    s = scene()
    perception = calibrated(params(), [wooden(f) for f in s.empty(20)])
    frames = []
    for i in range(30):
        f = wooden(s.render(i))
        f[30:90, 40:110] = lit(f[30:90, 40:110], 0.6)
        frames.append(f)
    assert all(not r.anchors for r in run(perception, frames, 0.0))


def test_a_light_switch_is_reported_and_the_anchors_survive_it() -> None:
    s = scene(still((40, 40, 220), 0.3, 0.35), still((40, 200, 40), 0.7, 0.65))
    perception = calibrated(params(), scene().empty(20))
    before = run(perception, [s.render(i) for i in range(20)], 0.0)
    ids = {a.id for a in before[-1].anchors}
    assert len(ids) == 2 and before[-1].light is not None and before[-1].light.steady
    after = run(perception, [lit(s.render(i), 0.5) for i in range(20, 60)], 2.0)
    changed = [r.t for r in after if r.light is not None and r.light.changed]
    assert changed and changed[0] - 2.0 < 0.5  # reported at once
    last = after[-1]
    assert last.light is not None and last.light.gain[0] == pytest.approx(0.5, abs=0.05)
    assert last.light.steady and last.light.changes == 1  # recovered within the 4 s
    assert {a.id for a in last.anchors} == ids
    assert all(len(r.anchors) == 2 for r in after)


def test_a_switch_between_frames_far_apart_is_seen_and_drift_is_not() -> None:
    """At 2 frames a second the window of 0.25 s holds no earlier frame: the last one counts.
    Drift of 40 % over a minute at 10 frames a second is no sudden change."""
    sparse = ChangeDetector(LightParams())
    assert [sparse.update(t, g, 0.0, at_rest) for t, g in ((0.0, 1.0), (0.5, 1.0), (1.0, 0.5))] == [
        Change.NONE,
        Change.NONE,
        Change.GLOBAL,
    ]
    drift = ChangeDetector(LightParams())
    assert all(
        drift.update(k / 10, 1.0 - 0.4 * k / 600, 0.0, at_rest) is Change.NONE for k in range(601)
    )
    assert drift.count == 0 and sparse.count == 1


def at_rest() -> float:
    """What ``moved`` gives for a view at rest."""
    return 0.0


def test_a_jump_of_the_foreground_is_relearned_only_once_the_view_is_still() -> None:
    """A body walking past close to the camera keeps moving and goes: held, never re-learned,
    no change counted (nor the gain it drags along). A lamp's change comes to rest: re-learned
    after ``confirm`` seconds of a still view."""
    walker = ChangeDetector(LightParams())
    shares = [0.0, 0.5, 0.8, 0.6, 0.05, 0.0]
    gains = [1.0, 1.0, 0.2, 0.9, 1.0, 1.0]
    changes = [
        walker.update(k / 5, g, s, lambda: 0.3)
        for k, (g, s) in enumerate(zip(gains, shares, strict=True))
    ]
    assert changes == [Change.NONE] * 6 and walker.count == 0 and not walker.holding
    lamp = ChangeDetector(LightParams(confirm=0.3))
    holding = []
    for t, share, moved in [(0.0, 0.0, 0.0), (0.2, 0.6, 0.9), (0.4, 0.6, 0.01)]:
        assert lamp.update(t, 1.0, share, lambda m=moved: m) is Change.NONE
        holding.append(lamp.holding)
    assert holding == [False, True, True]
    assert lamp.update(0.5, 1.0, 0.6, at_rest) is Change.UNEXPLAINED  # still since 0.2
    assert lamp.count == 1 and not lamp.holding


def test_a_body_walking_past_close_to_the_camera_is_neither_light_nor_an_object() -> None:
    """At 5 frames a second a dark body crossing near the lens covers most of the view between
    two frames: no re-learning, no change of light, no anchor; the view is clean after it."""
    body = Blob((25, 25, 30), (0.6, 1.4), ((10, -0.4, 0.5), (14, 1.4, 0.5)))
    s = scene(body)
    perception = calibrated(params(), scene().empty(20))
    results = [perception.process(s.render(i), i / 5) for i in range(20)]
    # the calibrated model alone: the body covers more than half the view in one frame
    assert max(perception.foreground(s.render(i)).mean() for i in range(10, 15)) > 0.5 * 255
    assert all(not r.anchors for r in results)
    last = results[-1].light
    assert last is not None and last.relearned == 0 and last.changes == 0
    assert (results[-1].masks.foreground > 0).mean() < 0.005


def test_a_body_covering_the_view_is_no_change_of_light() -> None:
    """At 15 frames a second a body wider than the view passes slowly, covering all of it for a
    few frames: no jump of the foreground to hold, and no fit on what is left of the floor,
    which would take the body's colours for the light and report a switch."""
    body = Blob((25, 25, 30), (1.3, 1.4), ((10, -0.7, 0.5), (34, 1.7, 0.5)))
    s = scene(body)
    perception = calibrated(params(), scene().empty(20))
    results = [perception.process(s.render(i), i / 15) for i in range(45)]
    assert max((perception.foreground(s.render(i)) > 0).mean() for i in range(10, 35)) > 0.95
    last = results[-1].light
    assert last is not None and last.changes == 0 and last.relearned == 0
    assert all(r.light is not None and abs(r.light.gain[0] - 1.0) < 0.05 for r in results)


def test_a_change_the_gain_cannot_explain_is_relearned_without_losing_anchors() -> None:
    """One lamp of two goes off: the left half of the view darkens far more than the right."""
    s = scene(still((40, 40, 220), 0.3, 0.35), still((40, 200, 40), 0.7, 0.65))
    perception = calibrated(params(), scene().empty(20))
    ids = {a.id for a in run(perception, [s.render(i) for i in range(20)], 0.0)[-1].anchors}
    light = np.tile(np.linspace(0.35, 1.1, W, dtype=np.float32), (H, 1))
    after = run(perception, [lit(s.render(i), light) for i in range(20, 50)], 2.0)
    last = after[-1]
    assert last.light is not None and last.light.relearned >= 1
    assert {a.id for a in last.anchors} == ids
    boxes = np.zeros((H, W), bool)
    for a in last.anchors:
        x, y, w, h = (round(v) for v in a.bbox)
        boxes[max(y - 3, 0) : y + h + 3, max(x - 3, 0) : x + w + 3] = True
    assert (last.masks.foreground[~boxes] > 0).mean() < 0.01


def test_a_switch_while_the_head_pans_is_compensated_against_the_view() -> None:
    """The head pans on (the background brought into each view from the map over directions)
    and the light drops to 60 % in one frame: reported, the same two anchors, the floor not
    foreground; without light adaptation the whole view is foreground and makes an anchor."""
    camera = CameraModel.from_opening_angles(math.radians(60), math.radians(47), W, H)
    cubes = [Cube(RED, 0.6, 0.0), Cube(GREEN, 0.55, 0.15)]
    pans = [0.0] * 10 + [0.003 * k for k in range(70)]

    def panning(p: PerceptionParams) -> tuple[Perception, list[FrameResult]]:
        rng = np.random.default_rng(1)
        perception = Perception(p, W, H, camera)
        empty = [render([], 0, camera, head_pose(0.0), rng)[0] for _ in range(30)]
        perception.calibrate(empty, poses=[head_pose(0.0)] * 30)
        results = []
        for f, pan in enumerate(pans):
            image = render(cubes, f, camera, head_pose(pan), rng)[0]
            results.append(
                perception.process(lit(image, 0.6 if f >= 50 else 1.0), f / FPS, head_pose(pan))
            )
        return perception, results

    perception, results = panning(params())
    assert perception.tracker.created_count == 2
    assert all({a.id for a in r.anchors} == {"o1", "o2"} for r in results[20:])
    assert all((r.masks.fg > 0).mean() < 0.1 for r in results[20:])
    light = [r.light for r in results]
    assert all(s is not None for s in light)
    assert [s.changed for s in light].index(True) == 50 and light[-1].changes == 1
    assert light[-1].gain[0] == pytest.approx(0.6, abs=0.03) and light[-1].steady
    frozen, results = panning(params(enabled=False))
    assert (results[-1].masks.fg > 0).mean() > 0.5 and frozen.tracker.created_count > 2


def test_a_ghost_from_the_calibration_is_relearned_not_anchored() -> None:
    """Someone stood at the right during the whole calibration and has gone."""
    person = still((60, 50, 140), 0.75, 0.45, size=0.3)
    calibration = [scene(person).render(i) for i in range(20)]
    perception = calibrated(params(), calibration)
    results = run(perception, [scene().render(100 + i) for i in range(20)], 0.0)
    assert all(not r.anchors for r in results[2:])
    last = results[-1]
    assert last.light is not None and last.light.ghosts >= 1
    assert (last.masks.foreground > 0).mean() < 0.005
    frozen = calibrated(params(enabled=False), calibration)
    assert run(frozen, [scene().render(100 + i) for i in range(20)], 0.0)[-1].anchors


def test_an_anchor_born_on_a_ghost_as_its_person_walks_off_goes_with_the_ghost() -> None:
    """Someone stood at the top during the whole calibration, then walks off slowly to the
    right: for five seconds the place they leave is foreground joined to their moving body, and
    an anchor is born on it. Once they are gone the place is still, and it is a ghost all the
    same under the anchor: re-learned, and the anchor has nothing left to see."""
    calibration = [scene(still((60, 50, 140), 0.45, 0.15, size=0.3)).render(i) for i in range(20)]
    path = ((0, 0.45, 0.15), (10, 0.45, 0.15), (60, 0.95, 0.15), (70, 1.3, 0.15))
    person = Blob((60, 50, 140), (0.3, 0.3), path)
    perception = calibrated(params(), calibration)
    results = run(perception, [scene(person).render(i) for i in range(140)], 0.0)
    assert any(r.anchors for r in results[70:80])  # left on the ghost as the person went
    assert all(not r.anchors for r in results[110:])  # a ghost for 3 s (GHOST_HOLD) is tested
    assert results[-1].light is not None and results[-1].light.ghosts >= 1


def test_an_anchored_still_object_is_never_absorbed() -> None:
    """Two minutes of a still object under light drifting by a quarter, a frame every 0.4 s,
    maintained at every frame with a time constant of 1 s: the quiet floor follows the light
    hundreds of times over, the object stays the one anchor and foreground."""
    p = params(maintain_every=0.1, maintain_time=1.0, quiet=0.5)
    s = scene(still((40, 40, 220), 0.4, 0.5))
    perception = calibrated(p, scene().empty(20))
    views = [s.render(i) for i in range(10)]
    frames = 300
    ramp = np.linspace(1.0, 0.75, frames)
    ids: set[str] = set()
    for i in range(frames):
        r = perception.process(lit(views[i % 10], ramp[i]), 0.4 * i)
        ids |= {a.id for a in r.anchors}
    assert ids == {"o1"}
    fg = r.masks.foreground
    assert (fg[int(0.43 * H) : int(0.57 * H), int(0.33 * W) : int(0.47 * W)] > 0).mean() > 0.95
    assert (fg > 0).mean() < 0.05


def test_a_maintenance_step_is_numpys_whole_model_update_to_the_bit() -> None:
    # The step follows the frame only where quiet, then the bounds come from the new mean: the
    # whole-array formulation it replaced, on a rendered table in dimmer light.
    table = scene(still((40, 160, 60), 0.5, 0.5))
    p = PerceptionParams()
    model = BackgroundModel.calibrate(table.empty(10), p.background)
    frame = to_ycrcb(lit(table.render(0), 0.9))
    maintenance = Maintenance(model.shape, p.light)
    rng = np.random.default_rng(0)
    maintenance.busy[:] = rng.choice([-np.inf, 0.5, 2.9], model.shape)
    anchored = np.zeros(model.shape, bool)
    anchored[40:90, 60:120] = True
    quiet = (3.0 - maintenance.busy >= p.light.quiet) & ~anchored
    rate = np.float32(1.0 - math.exp(-0.5 / p.light.maintain_time))
    step = frame.astype(np.float32)
    step -= model.mean
    step *= (rate * quiet)[..., None]
    expected = BackgroundModel(model.mean + step, model.sigma, p.background)
    maintenance.due(2.5)
    assert maintenance.step(model, frame, anchored, 3.0) == quiet.sum() > 0
    assert np.array_equal(model.mean, expected.mean)
    assert np.array_equal(model.lower, expected.lower)
    assert np.array_equal(model.upper, expected.upper)


def random_model(rng: np.random.Generator, height: int, width: int) -> BackgroundModel:
    """A model of random means and deviations, some of them below ``sigma_min``."""
    mean, sigma = rng.uniform(0, 255, (height, width, 3)), rng.uniform(0, 6, (height, width, 3))
    return BackgroundModel(mean, sigma, PerceptionParams().background)


def photometries(rng: np.random.Generator) -> list[Photometry]:
    """Photometries of real light (gains 0.3-3, offsets within 60 grey levels), ones that
    saturate at 0 and 255 and extreme ones."""
    gains, offsets = rng.uniform(0.3, 3, (3, 3)), rng.uniform(-60, 60, (3, 3))
    return [
        *(Photometry(tuple(g), tuple(o), 9) for g, o in zip(gains, offsets, strict=True)),
        Photometry((0.3, 0.4, 0.5), (60.0, 50.0, 40.0), 9),
        Photometry((3.0, 2.5, 2.0), (-60.0, -50.0, -40.0), 9),
        Photometry((1e-9, 1e5, 1.0), (1e9, -1e-30, 1e-30), 9),
    ]


def on_half(rng: np.random.Generator, pixel: np.ndarray) -> Photometry:
    """A photometry of real gains whose map in float32 puts each channel of ``pixel`` on a half
    grey level, where rounding the product before the sum would tell."""
    gain = tuple(rng.uniform(0.3, 3, 3))
    m = Photometry(gain, (0.0, 0.0, 0.0), 9).matrix.astype(np.float32)
    offset = []
    for c, centre in enumerate((0.0, 128.0, 128.0)):
        # matrix[c, 3] = centre - (centre + o) / g, wanted: level + 0.5 - matrix[c, c] * value
        wanted = rng.integers(1, 254) + 0.5 - float(m[c, c]) * int(pixel[c])
        offset.append((centre - wanted) * gain[c] - centre)
    return Photometry(gain, (offset[0], offset[1], offset[2]), 9)


@pytest.mark.parametrize("width", [1, 7, 16, 17, 33, 176, 177])
def test_the_light_pass_maps_and_tests_a_frame_as_opencv_does_to_the_bit(width: int) -> None:
    # The one compiled pass against cv2.transform (the map OpenCV gives the photometry's matrix)
    # and the model's cv2.inRange test, without the shadow test; rows of any width, so that
    # OpenCV's vector code and its tail both meet the kernel, and pixels of the first row and of
    # the last column mapped onto half grey levels.
    rng = np.random.default_rng(width)
    model = random_model(rng, 5, width)
    light = replace(LightParams(), shadows=False)
    ycc = rng.integers(0, 256, (5, width, 3), dtype=np.uint8)
    halves = [on_half(rng, ycc[0, u]) for u in range(min(width, 8))]
    halves += [on_half(rng, ycc[v, -1]) for v in range(5)]
    for photometry in [IDENTITY, *photometries(rng), *halves]:
        frame, raw = foreground(ycc, photometry, model, light)
        mapped = ycc if photometry.inliers == 0 else cv2.transform(ycc, photometry.matrix)
        assert np.array_equal(frame, mapped)
        assert np.array_equal(raw, model.classify(frame))
        # A moving head's frame, on the bounds of its view: the same pass without shadows.
        lower, upper = model.lower[:, ::-1].copy(), model.upper[:, ::-1].copy()
        frame, raw = view_foreground(ycc, photometry, lower, upper)
        assert np.array_equal(frame, mapped)
        inside = cv2.inRange(mapped, lower, upper)
        assert np.array_equal(raw, cv2.threshold(inside, 0, 1, cv2.THRESH_BINARY_INV)[1])


def test_the_light_pass_rounds_once_or_twice_as_this_machines_opencv_does() -> None:
    # OpenCV's code for CPUs with fused multiply-add rounds the map's product and sum once, its
    # code for older CPUs twice; the pass is told which (the test above holds either way). The
    # probe tells them apart, and rounded twice every level is numpy's float32 map.
    from percept.perception.light.foreground import FUSE_PROBE
    from percept.perception.light.foreground_kernels import light_foreground

    gain, offset, level = FUSE_PROBE
    probe = np.zeros((3, 4), np.float32)
    probe[:, 3], probe[[0, 1, 2], [0, 1, 2]] = offset, gain
    rng = np.random.default_rng(3)
    model = random_model(rng, 6, 33)
    ycc = rng.integers(0, 256, (6, 33, 3), dtype=np.uint8)
    ycc[0, 0] = level
    frame, raw = np.empty_like(ycc), np.empty((6, 33), np.uint8)

    def mapped(matrix: np.ndarray, fused: bool) -> np.ndarray:
        light_foreground(
            ycc, matrix, True, fused, model.lower, model.upper, model.mean, model.sigma,
            model.params.sigma_min, False, 0.0, 0.0, frame, raw,
        )  # fmt: skip
        return frame.copy()

    assert mapped(probe, True)[0, 0, 0] == 68 and mapped(probe, False)[0, 0, 0] == 69
    for photometry in photometries(rng)[:5]:
        matrix = photometry.matrix.astype(np.float32)
        twice = ycc.astype(np.float32) * np.diag(matrix).astype(np.float32) + matrix[:, 3]
        assert np.array_equal(mapped(matrix, False), np.rint(np.clip(twice, 0, 255)))


def test_the_light_pass_drops_the_shadows_the_test_describes() -> None:
    # The shadow test written out in numpy, on a model's pixels darkened to a random fraction
    # of their mean with their chroma scaled alike (and noise), half of them grey.
    rng = np.random.default_rng(5)
    model = random_model(rng, 40, 61)
    model.mean[:, :30, 1:] = 128.0  # grey: no shadow told from a grey object
    model = BackgroundModel(model.mean, model.sigma, model.params)
    r = rng.uniform(0.2, 1.1, (40, 61, 1))
    shaded = np.concatenate([model.mean[..., :1] * r, 128 + r * (model.mean[..., 1:] - 128)], 2)
    ycc = np.clip(np.rint(shaded + rng.normal(0, 1.5, shaded.shape)), 0, 255).astype(np.uint8)
    light = LightParams()
    frame, raw = foreground(ycc, IDENTITY, model, light)
    ratio = ycc[..., 0].astype(np.float32) / np.maximum(model.mean[..., 0], np.float32(1.0))
    bound = light.shadow_chroma * np.maximum(model.sigma[..., 1:], model.params.sigma_min)
    expected = 128.0 + ratio[..., None].astype(np.float64) * (model.mean[..., 1:] - 128.0)
    shadow = (
        (ratio >= light.shadow_darkest)
        & (ratio < 1.0)
        & (np.abs(ycc[..., 1:] - expected) <= bound).all(axis=2)
        & (np.abs(expected - 128.0) > bound).any(axis=2)
    )
    test = model.classify(ycc)
    assert frame is ycc
    assert np.array_equal(raw, test * ~shadow)
    assert shadow[test > 0].sum() > 200 and (test * shadow)[:, :30].sum() == 0


def test_a_photometrys_map_undoes_its_gain_and_offset() -> None:
    # expected = (observed - C - offset) / gain + C, C = 0 for Y and 128 for Cr and Cb; the
    # same from the gains and offsets given or from the fit's array of them.
    photometry = Photometry((0.5, 2.0, 1.0), (3.0, -4.0, 0.0), 9)
    fitted = np.zeros((4, 3))
    fitted[0], fitted[1], fitted[2] = photometry.gain, photometry.offset, 1.0
    for p in (photometry, Photometry.of(fitted, 9)):
        observed = np.array([0.5 * 100 + 3.0, 128 + 2.0 * 10 - 4.0, 77.0, 1.0])
        assert np.allclose(p.matrix @ observed, [100.0, 138.0, 77.0])


@pytest.mark.parametrize("seed", range(3))
def test_the_lights_frame_call_is_its_steps_one_by_one(seed: int) -> None:
    # The compiled call of a frame composes the anchors' box mask, the photometric fit, the one
    # pass and the share outside the anchors: the same to the bit as the steps called one by
    # one, with no photometry yet, one that holds, and one the fit replaces.
    from percept.perception.light.adaptation_kernels import light_frame
    from percept.perception.light.foreground import opencv_fuses
    from percept.perception.light.maintenance import box_mask
    from percept.perception.light.masks_kernels import share_outside
    from percept.perception.light.photometry.photometric import (
        CENTRE,
        HOLD,
        MIN_SPREAD,
        on_grid,
        sample_step,
    )

    rng = np.random.default_rng(seed)
    model = random_model(rng, 48, 64)
    light = LightParams()
    gain = np.array([0.8, 0.9, 1.1]) if seed else np.ones(3)
    seen = 128 + gain * (model.mean - 128) + rng.normal(0, 1.0, model.mean.shape)
    seen[..., 0] = model.mean[..., 0] * gain[0]
    ycc = np.clip(np.rint(seen), 0, 255).astype(np.uint8)
    ycc[10:22, 5:25] = (200, 90, 160)  # an object the fit must leave out
    previous = (rng.random((48, 64)) < 0.1).astype(np.uint8)
    boxes = np.array([[8.0, 16.0, 30.0, 14.0], [60.0, 40.0, 40.0, 30.0]])
    step, sample = 2, sample_step((48, 64), 300)
    expected = on_grid(model.mean, sample)
    anchored = box_mask(boxes, (48, 64), step)
    fitted = fit(ycc, expected, anchored, previous, sample, IDENTITY, 0.1, 0.6)
    assert fitted.inliers > 0
    for current in (IDENTITY, fitted, photometries(rng)[0]):
        photometry = fit(ycc, expected, anchored, previous, sample, current, 0.1, 0.6)
        frame, raw = foreground(ycc, photometry, model, light)
        out, raw_out = np.empty_like(ycc), np.empty((48, 64), np.uint8)
        painted = np.ones((48, 64), bool)
        kept, inliers, compensated, share = light_frame(
            ycc, boxes, step, painted, True, expected, previous, sample, current.fitted,
            current.inliers, 0.1, 0.6, CENTRE, MIN_SPREAD, HOLD, opencv_fuses(), model.lower,
            model.upper, model.mean, model.sigma, model.params.sigma_min, light.shadows,
            light.shadow_darkest, light.shadow_chroma, out, raw_out,
        )  # fmt: skip
        assert np.array_equal(painted, anchored)
        assert (inliers < 0) == (photometry is current)
        assert np.array_equal(kept, photometry.fitted)
        assert compensated == (photometry.inliers != 0)
        assert np.array_equal(out if compensated else ycc, frame)
        assert np.array_equal(raw_out, raw)
        assert share == share_outside(raw, anchored, sample)


def test_light_params_are_validated() -> None:
    from percept.config.loader import ConfigError, build

    with pytest.raises(ConfigError, match="shadow_darkest"):
        build(LightParams, {"shadow_darkest": 2.0}, "x.toml")
