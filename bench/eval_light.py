"""A background that lasts a lab session (issue 18), against ground truth; prints one report.

- ``day``: the simulated ``tabletop-day`` scene (5.5 min: light drifting 40 %, a lamp switched
  off and on, an exposure step up and back, people walking through during the calibration and
  after, objects put down and left; robot a, the first 2 s calibrate): MOTA, IDF1, false
  anchors (anchors that match no object in most frames they are seen in), anchors living
  longer than 2 s that are not objects, per sudden change the delay until the status reports it
  and until the light is steady again and the foreground outside the anchors is back, anchors
  lost across it, and for each object put down how long until it is anchored and whether the
  same anchor holds it at the end. With light adaptation and without (the frozen model).
- ``speed``: ms per frame (median, p90, one thread) with and without light adaptation on the
  first minute of ``tabletop-day``, the two pipelines taking turns frame by frame.
- ``tud``: MOT15 TUD-Campus and TUD-Stadtmitte (people walking, nothing put down; background
  from all frames, as ``eval_quality.py``): the anchors living longer than 2 s and what they are.
- ``cdnet``: CDnet 2014 highway F1 of :meth:`Perception.foreground` (the calibrated model, as the
  README reports it) and of :meth:`Perception.process` with the light adaptation.
- ``figures``: ``tabletop-day`` with only its people (nothing is put down; light, exposure and
  walking as in the scene, one standing and one crossing during the calibration): every anchor
  made, and those living longer than 2 s with what they were on (a person, by the truth's boxes,
  or nothing).
- ``soak``: ``tabletop-day``'s room for ``--soak-minutes`` (10; 60 for the issue's hour) at
  ``--soak-fps`` (5) with the light drifting up and down by 40 % every 20 minutes and the
  exposure stepping every 10: anchors over time, false anchors at checks every 5 s, memory
  (resident set) after the first tenth and at the end.

    python bench/eval_light.py [--only day speed tud cdnet figures soak] [--day-dir DIR]
                               [--soak-minutes M] [--soak-fps F] [--figures-fps F] [--skip-off]
                               [--set KEY=VALUE ...]

``--day-dir`` keeps the rendered scene (rendered there when missing: ``percept sim --scene
tabletop-day --robot a --out DIR``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.eval_quality import cdnet_data  # noqa: E402
from percept.drivers.sim.scene import Event, Scene  # noqa: E402
from percept.drivers.sim.world import SimWorld  # noqa: E402
from percept.perception.evaluation.tracking import (  # noqa: E402
    evaluate_tracking,
    iou,
    mot_box,
    read_mot,
)
from percept.perception.params import PerceptionParams  # noqa: E402
from percept.perception.pipeline import FrameResult, Perception  # noqa: E402
from percept.perception.tracking.anchors import Anchor  # noqa: E402
from percept.runtime.commands._sequence import open_sequence  # noqa: E402
from percept.runtime.commands.offline import _perception_params  # noqa: E402
from percept.runtime.settings.scene import find_scene, load_scene  # noqa: E402

DATA = REPO.parent / "shared" / "data"
MATCH = 0.3
"""IoU with a true box for an anchor to be on that object."""
LONG = 2.0
CDNET_FPS = 30.0
"""Seconds: the issue's bound on the life of an anchor on something that is no object."""


def variants(base: PerceptionParams, off: bool) -> dict[str, PerceptionParams]:
    """percept as configured, and with light adaptation off when ``off``."""
    if not off:
        return {"percept": base}
    return {
        "percept": base,
        "percept, light off": replace(base, light=replace(base.light, enabled=False)),
    }


def _calibrating_on(params: PerceptionParams, frames: int) -> PerceptionParams:
    return replace(params, background=replace(params.background, calibration_frames=frames))


# -- one run ----------------------------------------------------------------------------------


@dataclass
class AnchorLife:
    """One anchor over a run: when it was seen, and how well it matched the truth."""

    first: float
    last: float = 0.0
    seen: int = 0
    matched: int = 0
    truth: dict[int, int] = field(default_factory=lambda: defaultdict(int))
    """True id -> frames the anchor matched it in."""
    box: tuple[float, ...] = ()

    @property
    def life(self) -> float:
        return self.last - self.first

    @property
    def false(self) -> bool:
        """It matched no true object in most of the frames it was seen in."""
        return self.matched < 0.5 * self.seen


@dataclass
class Run:
    """What one run of the pipeline over a sequence gave."""

    rows: list[tuple] = field(default_factory=list)
    anchors: dict[str, AnchorLife] = field(default_factory=dict)
    results: list[tuple[float, object, set[str], float]] = field(default_factory=list)
    """(t, light status, ids alive, foreground share outside the anchors' boxes) per frame."""
    ms: list[float] = field(default_factory=list)
    size: tuple[int, int] = (0, 0)


def _truth_by_frame(gt: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Frame -> (ids, 0-based boxes) of the MOT ground truth."""
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for frame in np.unique(gt[:, 0]).astype(int):
        rows = gt[gt[:, 0] == frame]
        boxes = rows[:, 2:6].copy()
        boxes[:, :2] -= 1  # the image boxes of MOT boxes (tracking.mot_box's inverse)
        out[frame] = (rows[:, 1].astype(int), boxes)
    return out


def _outside_share(result: FrameResult) -> float:
    """Share of the foreground outside every anchor's box (0 for a skipped frame)."""
    if result.masks is None:
        return 0.0
    fg = result.masks.foreground > 0
    for a in result.anchors:
        x, y, w, h = (round(v) for v in a.bbox)
        fg[max(y, 0) : y + h, max(x, 0) : x + w] = False
    return float(fg.mean())


def follow_lives(
    lives: dict[str, AnchorLife], result: FrameResult, t: float, ids: np.ndarray, boxes: np.ndarray
) -> list[Anchor]:
    """Note each anchor of ``result`` (at time ``t``) in ``lives``, and match those seen to the
    true ``boxes`` (0-based, with their ``ids``) at IoU :data:`MATCH`; the anchors seen."""
    seen = []
    for a in result.anchors:
        life = lives.setdefault(a.id, AnchorLife(first=t))
        life.last, life.box = t, a.bbox
        if not a.visible or result.skipped:
            continue
        seen.append(a)
        life.seen += 1
        if len(boxes):
            overlap = iou(np.array([a.bbox]), boxes)[0]
            if overlap.max() >= MATCH:
                life.matched += 1
                life.truth[int(ids[overlap.argmax()])] += 1
    return seen


def run_pipeline(
    params: PerceptionParams,
    frames: Iterable[tuple[float, np.ndarray]],
    calibration: int,
    gt: np.ndarray,
) -> Run:
    """Calibrate on the first ``calibration`` frames (they are processed too, like ``percept
    track``) and process every frame; anchors are matched to ``gt`` as they go."""
    frames = iter(frames)
    first = [next(frames) for _ in range(calibration)]
    h, w = first[0][1].shape[:2]
    perception = Perception(_calibrating_on(params, calibration), w, h)
    perception.calibrate(im for _, im in first)
    truth = _truth_by_frame(gt)
    out = Run(size=(w, h))
    for index, (t, image) in enumerate(itertools.chain(first, frames), start=1):
        start = time.perf_counter()
        result = perception.process(image, t)
        out.ms.append((time.perf_counter() - start) * 1e3)
        ids, boxes = truth.get(index, (np.zeros(0, int), np.zeros((0, 4))))
        for a in follow_lives(out.anchors, result, t, ids, boxes):
            out.rows.append((index, a.number, *mot_box(a.bbox), 1, -1, -1, -1))
        alive = {a.id for a in result.anchors}
        out.results.append((t, result.light, alive, _outside_share(result)))
    return out


def _tracking(run: Run, gt: np.ndarray) -> dict:
    rows = np.array(run.rows, float).reshape(-1, 10)
    return evaluate_tracking(gt, rows, image_size=run.size).as_dict()


# -- the day scene ----------------------------------------------------------------------------


def _render_day(folder: Path) -> None:
    if (folder / "gt" / "gt.txt").exists():
        return
    command = ["sim", "--scene", "tabletop-day", "--robot", "a", "--out", str(folder)]
    subprocess.run([sys.executable, "-m", "percept.runtime.cli", *command], cwd=REPO, check=True)


def _sudden(scene: Scene) -> list[tuple[float, str]]:
    """The scene's switches and exposure steps (events of no duration)."""
    return [
        (e.t, e.action)
        for e in scene.timeline
        if e.action in ("lights", "exposure") and e.span == 0
    ]


def _placed(scene: Scene) -> list[tuple[float, int]]:
    """Objects (no figures) put down after the first 10 s: (time, id)."""
    figures = {o.id for o in scene.objects if o.is_figure}
    return [
        (e.t, e.object)
        for e in scene.timeline
        if e.action == "add" and e.t > 10 and e.object is not None and e.object not in figures
    ]


def _change_rows(run: Run, scene: Scene) -> Iterator[dict]:
    times = np.array([r[0] for r in run.results])
    for t0, action in _sudden(scene):
        if t0 + 3 > times[-1]:
            continue
        after = [r for r in run.results if t0 <= r[0] <= t0 + 10]
        before = [r for r in run.results if t0 - 10 <= r[0] < t0]
        reported = next((r[0] - t0 for r in after if r[1] is not None and r[1].changed), None)
        steady = next(
            (r[0] - t0 for r in after if r[0] > t0 + 0.1 and r[1] is not None and r[1].steady), None
        )
        calm = max(2 * float(np.median([r[3] for r in before])), 0.002)
        back = next((r[0] - t0 for r in after if r[0] > t0 and r[3] <= calm), None)
        alive_before = run.results[int(np.searchsorted(times, t0)) - 1][2]
        alive_after = run.results[int(np.searchsorted(times, t0 + 3))][2]
        lost = sorted(i for i in alive_before - alive_after if not run.anchors[i].false)
        yield {
            "change": f"{action} at {t0:g} s",
            "reported": reported,
            "steady": steady,
            "foreground back": back,
            "anchors lost": lost,
        }


def _placed_rows(run: Run, scene: Scene, gt: np.ndarray, fps: float) -> Iterator[dict]:
    end = max(r[0] for r in run.results)
    for t0, obj in _placed(scene):
        holders = [
            (life.first, anchor)
            for anchor, life in run.anchors.items()
            if life.truth.get(obj, 0) >= 0.5 * life.seen and life.seen
        ]
        seen = gt[gt[:, 1] == obj]
        shown = float(seen[:, 0].min() - 1) / fps if len(seen) else None
        if not holders or shown is None:
            yield {"object": obj, "put down": t0, "anchored after": None}
            continue
        first, anchor = min(holders)
        life = run.anchors[anchor]
        yield {
            "object": obj,
            "put down": t0,
            "anchored after": round(first - shown, 3),
            "anchor": anchor,
            "held to": round(life.last, 2),
            "held at the end": life.last >= end - 0.1,
        }


def day(base: PerceptionParams, off: bool, folder: Path | None) -> Iterator[dict]:
    scene, _ = load_scene(find_scene("tabletop-day"))
    with tempfile.TemporaryDirectory() as tmp:
        out = folder or Path(tmp) / "day"
        _render_day(out)
        sequence = open_sequence(out)
        gt = read_mot(out / "gt" / "gt.txt")
        fps = sequence.fps
        for label, params in variants(base, off).items():
            frames = ((t, im) for _, t, im in sequence.frames())
            run = run_pipeline(params, frames, int(2 * fps), gt)
            false = {i: life for i, life in run.anchors.items() if life.false}
            yield {
                "data": "sim tabletop-day (a)",
                "method": label,
                **_tracking(run, gt),
                "ms": float(np.median(run.ms)),
                "ms p90": float(np.percentile(run.ms, 90)),
                "anchors": len(run.anchors),
                "false anchors": len(false),
                "false anchors > 2 s": {
                    i: (round(life.first, 2), round(life.life, 2), [round(v) for v in life.box])
                    for i, life in false.items()
                    if life.life > LONG
                },
                "changes": list(_change_rows(run, scene)),
                "placed": list(_placed_rows(run, scene, gt, fps)),
            }


def speed(base: PerceptionParams, folder: Path | None, seconds: float = 60.0) -> Iterator[dict]:
    """ms per frame with and without light adaptation on the first ``seconds`` of
    ``tabletop-day``, the two pipelines taking turns frame by frame (the same load on both)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = folder or Path(tmp) / "day"
        _render_day(out)
        sequence = open_sequence(out)
        frames = [(t, im) for _, t, im in sequence.frames(round(seconds * sequence.fps))]
    calibration = round(2 * sequence.fps)
    h, w = frames[0][1].shape[:2]
    pipelines = {}
    for label, params in variants(base, True).items():
        pipelines[label] = Perception(_calibrating_on(params, calibration), w, h)
        pipelines[label].calibrate(im for _, im in frames[:calibration])
    ms: dict[str, list[float]] = {label: [] for label in pipelines}
    for t, image in frames:
        for label, perception in pipelines.items():
            start = time.perf_counter()
            perception.process(image, t)
            ms[label].append((time.perf_counter() - start) * 1e3)
    for label, values in ms.items():
        yield {
            "data": f"speed, tabletop-day first {seconds:g} s ({w}x{h})",
            "method": label,
            "ms": round(float(np.median(values)), 3),
            "ms p90": round(float(np.percentile(values, 90)), 3),
        }


# -- TUD --------------------------------------------------------------------------------------


def tud(base: PerceptionParams, off: bool) -> Iterator[dict]:
    for name in ("TUD-Campus", "TUD-Stadtmitte"):
        folder = DATA / "mot15-tud" / name
        sequence = open_sequence(folder / f"{name}.mp4")
        frames = [(t, im) for _, t, im in sequence.frames()]
        gt = read_mot(folder / "gt" / "gt.txt")
        for label, params in variants(base, off).items():
            run = run_pipeline(params, frames, len(frames), gt)
            long = {i: life for i, life in run.anchors.items() if life.life > LONG}
            yield {
                "data": name,
                "method": label,
                "frames": len(frames),
                "seconds": round(len(frames) / sequence.fps, 2),
                "anchors": len(run.anchors),
                f"anchors > {LONG:g} s": len(long),
                "what": {
                    i: _what(life) for i, life in sorted(long.items(), key=lambda kv: kv[1].first)
                },
            }


def _what(life: AnchorLife) -> str:
    """What an anchor was on: the person it matched most, or nothing."""
    where = "box " + ",".join(str(round(v)) for v in life.box)
    lived = f"{life.first:.1f}-{life.last:.1f} s"
    if not life.truth:
        return f"no person ({where}, {lived}, matched in 0/{life.seen} frames)"
    person, frames = max(life.truth.items(), key=lambda kv: kv[1])
    return f"person {person} in {frames}/{life.seen} frames ({where}, {lived})"


# -- CDnet ------------------------------------------------------------------------------------


def cdnet(base: PerceptionParams) -> Iterator[dict]:
    """F1 of the calibrated model alone (``foreground``, the README's number), then of every
    frame through ``process`` with the light adaptation as configured."""
    frames, first, score = cdnet_data()
    h, w = frames[0].shape[:2]
    perception = Perception(_calibrating_on(base, first - 1), w, h)
    perception.calibrate(frames[: first - 1])
    masks = [perception.foreground(image) for image in frames[first - 1 :]]
    yield {"data": "CDnet highway", "method": "foreground() (calibrated model)", **score(masks)}
    masks = []
    for i, image in enumerate(frames[first - 1 :]):
        result = perception.process(image, i / CDNET_FPS)
        masks.append(result.masks.foreground if result.masks is not None else None)
    yield {"data": "CDnet highway", "method": "process(), light adaptation", **score(masks)}


# -- people only ------------------------------------------------------------------------------


def _figures_scene() -> tuple[Scene, dict]:
    """``tabletop-day`` with its figures and its light, and no object put down."""
    scene, platforms = load_scene(find_scene("tabletop-day"))
    people = {o.id for o in scene.objects if o.is_figure}
    return (
        replace(
            scene,
            name="figures",
            objects=tuple(o for o in scene.objects if o.id in people),
            timeline=tuple(e for e in scene.timeline if e.object is None or e.object in people),
        ),
        platforms,
    )


def figures(base: PerceptionParams, fps: float) -> Iterator[dict]:
    """Every anchor made while people walk through an empty table's view, and what the ones
    that live longer than 2 s are on (the issue: none should)."""
    scene, platforms = _figures_scene()
    calibration = round(2 * fps)
    with SimWorld(scene, platforms) as world:
        lens = world.camera_model("a")
        perception = Perception(_calibrating_on(base, calibration), lens.width, lens.height)
        perception.calibrate(world.render("a", k / fps) for k in range(calibration))
        lives: dict[str, AnchorLife] = {}
        for k in range(round(scene.duration * fps)):
            t = k / fps
            result = perception.process(world.render("a", t), t)
            view = world.truth(t, ["a"]).views["a"]
            people = {i: v.bbox for i, v in view.objects.items() if v.bbox}
            ids = np.array(list(people), int)
            follow_lives(lives, result, t, ids, np.array(list(people.values()), float))
    long = {i: life for i, life in lives.items() if life.life > LONG}
    yield {
        "data": f"tabletop-day, people only ({scene.duration:g} s at {fps:g} fps)",
        "method": "percept",
        "anchors": len(lives),
        f"anchors > {LONG:g} s": len(long),
        "what": {i: _what(life) for i, life in sorted(long.items(), key=lambda kv: kv[1].first)},
    }


# -- soak -------------------------------------------------------------------------------------


def _soak_scene(minutes: float) -> Scene:
    """``tabletop-day``'s room and objects 1-5, put down in the first 8 s and left; no people;
    the light drifting between 100 % and 60 % and back every 20 minutes (in one-minute ramps),
    the exposure stepping between 1 and 1.15 every 10 minutes."""
    scene, _ = load_scene(find_scene("tabletop-day"))
    keep = {1, 2, 3, 4, 5}
    seconds = minutes * 60
    events = [e for e in scene.timeline if e.action == "add" and e.object in keep and e.t < 10]
    for k in range(1, math.ceil(seconds / 60) + 1):
        level = 0.8 + 0.2 * math.cos(2 * math.pi * k * 60 / 1200)
        events.append(Event(t=10 + (k - 1) * 60, action="lights", scale=level, duration=60.0))
    for k in range(1, math.ceil(seconds / 600) + 1):
        events.append(Event(t=k * 600 - 300, action="exposure", scale=1.15 if k % 2 else 1.0))
    return replace(
        scene,
        name="soak",
        duration=seconds,
        objects=tuple(o for o in scene.objects if o.id in keep),
        timeline=tuple(events),
    )


def _rss_mib() -> float:
    for line in Path("/proc/self/status").read_text(encoding="utf-8").splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def soak(base: PerceptionParams, minutes: float, fps: float) -> Iterator[dict]:
    scene, platforms = load_scene(find_scene("tabletop-day"))
    scene = _soak_scene(minutes)
    frames = round(minutes * 60 * fps)
    with SimWorld(scene, platforms) as world:
        lens = world.camera_model("a")
        params = _calibrating_on(base, int(2 * fps))
        perception = Perception(params, lens.width, lens.height)
        perception.calibrate(world.render("a", k / fps) for k in range(int(2 * fps)))
        most, ids, false_ids, checks = 0, set(), set(), 0
        rss: list[tuple[float, float]] = []
        ms: list[float] = []
        for k in range(frames):
            t = k / fps
            image = world.render("a", t)
            start = time.perf_counter()
            result = perception.process(image, t)
            ms.append((time.perf_counter() - start) * 1e3)
            most = max(most, len(result.anchors))
            ids |= {a.id for a in result.anchors}
            if k % round(5 * fps) == 0 and t > 10:
                checks += 1
                view = world.truth(t, ["a"]).views["a"]
                boxes = np.array([v.bbox for v in view.objects.values() if v.bbox], float)
                for a in result.anchors:
                    if a.age > LONG and (
                        not len(boxes) or iou(np.array([a.bbox]), boxes).max() < MATCH
                    ):
                        false_ids.add(a.id)
            if k % round(60 * fps) == 0:
                rss.append((t, _rss_mib()))
        status = result.light
        yield {
            "data": f"soak {minutes:g} min at {fps:g} fps",
            "method": "percept",
            "frames": frames,
            "anchors at most": most,
            "anchors ever": len(ids),
            "anchors at the end": sorted(a.id for a in result.anchors),
            "false anchors (checks every 5 s)": sorted(false_ids),
            "checks": checks,
            "rss MiB after a tenth, at the end": (
                round(rss[max(len(rss) // 10, 1) if len(rss) > 1 else 0][1], 1),
                round(_rss_mib(), 1),
            ),
            "light at the end": None if status is None else status.as_dict(),
            "ms": float(np.median(ms)),
            "ms p90": float(np.percentile(ms, 90)),
        }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only",
        nargs="+",
        choices=["day", "speed", "tud", "cdnet", "figures", "soak"],
        default=["day", "speed", "tud", "cdnet", "figures", "soak"],
    )
    parser.add_argument("--day-dir", type=Path, help="keep the rendered tabletop-day scene here")
    parser.add_argument(
        "--soak-minutes", type=float, default=10.0, help="scene minutes (60: an hour)"
    )
    parser.add_argument("--soak-fps", type=float, default=5.0, help="frames per second of the soak")
    parser.add_argument(
        "--figures-fps", type=float, default=15.0, help="frames per second of the people-only run"
    )
    parser.add_argument(
        "--skip-off", action="store_true", help="leave out the runs with light adaptation off"
    )
    _perception_params.add_arguments(parser)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    base = _perception_params.params_from_args(args)
    runs = {
        "day": lambda: day(base, not args.skip_off, args.day_dir),
        "speed": lambda: speed(base, args.day_dir),
        "tud": lambda: tud(base, not args.skip_off),
        "cdnet": lambda: cdnet(base),
        "figures": lambda: figures(base, args.figures_fps),
        "soak": lambda: soak(base, args.soak_minutes, args.soak_fps),
    }
    for name in args.only:
        for row in runs[name]():
            print(json.dumps(row, default=str), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
