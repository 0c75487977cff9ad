"""The demo's summary: each robot's recording scored against the simulated truth, printed as a
table, written as ``summary.json`` and drawn as the chapter's Fig. 5.5 (``figure.png``)."""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple, NotRequired, TypedDict

import cv2

from percept.runtime.daemon.status.health import mean_shares
from percept.runtime.net.messages import ObjectId, Status, World
from percept.runtime.record import scorecard as sc
from percept.runtime.record.drawing import (
    MapMark,
    caption,
    draw_anchors,
    draw_map,
    draw_table,
    object_bgr,
    stack,
)

if TYPE_CHECKING:
    from percept.drivers.sim.world import SimWorld
    from percept.runtime.demo import DemoOptions
    from percept.runtime.games.monitor import AttentionEvent
    from percept.runtime.record.reader import RecordedFrame

log = logging.getLogger("percept.summary")

SAMPLE_EVERY = 10  # score every n-th world model (truth costs a little)


class RobotSummary(TypedDict):
    """One robot's row of the summary (the printed table's column)."""

    world_models: int
    anchors_mean: float | None
    mota: float | None
    """CLEAR-MOT accuracy of the anchors against the true objects on the ground (None: no
    true object was there)."""
    idf1: float | None
    false_anchors_mean: float | None
    """Anchors matched to no true object, per world model."""
    false_anchors_long: int
    """Anchors matched to no true object for more than 10 s in all."""
    anchors_end: int
    true_objects_end: int
    matched_end: int
    ground_error_m_median: float | None
    peer_position_error_m_median: float | None
    peer_heading_error_rad_median: float | None
    peer_pose_frames: str
    pointing_games: int
    pointing_success: int
    guessing_games: int
    guessing_success: int
    guessing_as_speaker: int
    guessing_success_late: float | None
    lexicon_size: int
    categories: int
    fps_mean: float | None
    cpu_cores_mean: float | None
    cpu_cores_by_thread: dict[str, float]
    """The mean of the statuses' ``cpu_threads``: cores of each thread of the daemon."""
    rss_mb_max: float | None


class FeatureDifference(TypedDict):
    """How far apart the robots' scaled features are for the objects both matched."""

    objects_seen_by_both: int
    mean_shared_features: float | None
    per_object: dict[str, dict[str, float]]


class Summary(TypedDict):
    """``summary.json``; the demo adds the daemons' exit codes and its run time."""

    scene: str
    robots: dict[str, RobotSummary]
    scaled_feature_difference: FeatureDifference
    joint_attention_events: int
    guessing_games_per_minute: float
    exit_codes: NotRequired[dict[str, int]]
    seconds: NotRequired[float]


class _Recorded(NamedTuple):
    """What the summary reads of a robot's recording: its world models (as recorded, read back
    as messages), its status messages and its last frame (None when it recorded none)."""

    worlds: list[World]
    statuses: list[Status]
    last: RecordedFrame | None


def _read(path: Path) -> _Recorded:
    from percept.runtime.record.reader import read_recording

    got = _Recorded([], [], None)
    for kind, item in read_recording(path):
        if kind == "world":
            got.worlds.append(World.from_json(item, f"{path} world"))
        elif kind == "status":
            got.statuses.append(Status.from_json(item, f"{path} status"))
        elif kind == "frame":
            got = got._replace(last=item)
    return got


class _End(NamedTuple):
    """A robot's end of the run: its last world model (None: it made none), its anchors matched
    to the true objects, the true objects, its last frame and the ids of its false anchors."""

    world: World | None
    matched: list[sc.Match]
    truth: list[sc.TruthObject]
    last: RecordedFrame | None
    false: frozenset[ObjectId]


def summarise(
    options: DemoOptions,
    records: dict[str, Path],
    epoch: float,
    events: Sequence[AttentionEvent],
) -> Summary:
    from percept.config import shipped_name
    from percept.runtime.settings.scene import open_world

    world = open_world(options.scene)
    robots = list(records)
    poses = {r: _pose2(world.scene.robot(r).pose) for r in robots}
    per_robot: dict[str, RobotSummary] = {}
    final: dict[str, _End] = {}
    for robot in robots:
        other = next((r for r in robots if r != robot), None)
        recorded = _read(records[robot])
        per_robot[robot], final[robot] = _robot_summary(
            recorded, world, epoch, poses[robot], None if other is None else (other, poses[other])
        )
    world.close()
    diffs = sc.scaled_differences({r: final[r].matched for r in robots}) if len(robots) > 1 else {}
    summary: Summary = {
        # A shipped scene by its name, not its place inside the installed package.
        "scene": shipped_name("scenes", options.scene) or str(options.scene),
        "robots": per_robot,
        "scaled_feature_difference": _feature_difference(diffs),
        "joint_attention_events": sum(e.get("event") == "joint_attention" for e in events),
        # Each game once, by its speaker, over the whole run (start-up included).
        "guessing_games_per_minute": round(
            sum(r["guessing_as_speaker"] for r in per_robot.values()) * 60 / options.seconds, 1
        ),
    }
    _print_table(summary)
    _figure(options.out / "figure.png", robots, final, poses, diffs)
    return summary


def _robot_summary(
    recorded: _Recorded,
    world: SimWorld,
    epoch: float,
    pose: sc.Pose2,
    other: tuple[str, sc.Pose2] | None,
) -> tuple[RobotSummary, _End]:
    """One robot's scores against the truth (every ``SAMPLE_EVERY``-th world model, and the
    last one), with ``other`` the other robot's name and true pose (None: it is alone); and
    its end."""
    worlds, statuses, last = recorded
    errors: list[float | None] = []
    peer_pos: list[float | None] = []
    peer_head: list[float | None] = []
    anchors: list[float | None] = []
    precision = sc.Precision(pose)
    for w in worlds[::SAMPLE_EVERY]:
        truth = _truth(world, w.stamp - epoch)
        precision.add(w, truth)
        matches = sc.match(w, truth, pose)
        errors += [d for _, _, d in matches]
        anchors.append(len(w.objects))
        if other is not None:
            name, other_pose = other
            err = sc.peer_error(w, name, sc.relative_pose(pose, other_pose))
            if err is not None:
                peer_pos.append(err[0])
                peer_head.append(err[1])
    end = worlds[-1] if worlds else None
    truth_end = _truth(world, (epoch if end is None else end.stamp) - epoch)
    matched = [] if end is None else sc.match(end, truth_end, pose)
    true_ids = {o.id for o, _, _ in matched}
    false = frozenset(() if end is None else (o.id for o in sc.placed(end) if o.id not in true_ids))
    mota, idf1 = precision.scores()
    games: Mapping[str, int] = statuses[-1].games if statuses else {}
    summary: RobotSummary = {
        "world_models": len(worlds),
        "anchors_mean": sc.mean(anchors),
        "mota": mota,
        "idf1": idf1,
        "false_anchors_mean": sc.mean(precision.false_counts),
        "false_anchors_long": precision.long_false(),
        "anchors_end": 0 if end is None else len(end.objects),
        "true_objects_end": len(truth_end),
        "matched_end": len(matched),
        "ground_error_m_median": sc.median(errors),
        "peer_position_error_m_median": sc.median(peer_pos),
        "peer_heading_error_rad_median": sc.median(peer_head),
        "peer_pose_frames": f"{len(peer_pos)}/{len(worlds[::SAMPLE_EVERY])}",
        "pointing_games": games.get("played", 0),
        "pointing_success": games.get("success", 0),
        "guessing_games": games.get("guessing_played", 0),
        "guessing_success": games.get("guessing_success", 0),
        "guessing_as_speaker": games.get("guessing_as_speaker", 0),
        "guessing_success_late": _late_success(statuses),
        "lexicon_size": games.get("lexicon_size", 0),
        "categories": games.get("categories", 0),
        "fps_mean": sc.mean([s.fps for s in statuses[2:]]),
        "cpu_cores_mean": sc.mean([s.cpu for s in statuses[2:]]),
        "cpu_cores_by_thread": {
            n: round(v, 3) for n, v in mean_shares([s.cpu_threads for s in statuses[2:]]).items()
        },
        "rss_mb_max": max((s.rss_mb or 0 for s in statuses), default=None),
    }
    return summary, _End(end, matched, truth_end, last, false)


def _late_success(statuses: Sequence[Status]) -> float | None:
    """The robot's guessing success over the later half of its games, from the counts in its
    statuses (None before two games): how far its agent has learnt."""
    if not statuses:
        return None
    end = statuses[-1].games
    played, won = end.get("guessing_played", 0), end.get("guessing_success", 0)
    half = next(s.games for s in statuses if s.games.get("guessing_played", 0) >= played / 2)
    games = played - half.get("guessing_played", 0)
    return None if played < 2 or games <= 0 else (won - half.get("guessing_success", 0)) / games


def _feature_difference(diffs: Mapping[int, Mapping[str, float]]) -> FeatureDifference:
    shared = [d[f] for d in diffs.values() for f in sc.SHARED if f in d]
    return {
        "objects_seen_by_both": len(diffs),
        "mean_shared_features": sc.mean(shared),
        "per_object": {str(k): {f: round(v, 4) for f, v in d.items()} for k, d in diffs.items()},
    }


def _pose2(pose: Sequence[float]) -> sc.Pose2:
    x, y, yaw = pose
    return x, y, yaw


def _truth(world: SimWorld, t: float) -> list[sc.TruthObject]:
    """The true objects at scene time ``t``; the figures (people walking through) are none."""
    truth = world.truth(max(0.0, t), views=[])
    return [
        sc.TruthObject(o.id, o.name, float(o.position[0]), float(o.position[1]), o.size, o.color)
        for o in truth.objects.values()
        if o.shape != "figure"
    ]


def _print_table(summary: Summary) -> None:
    rows: list[tuple[str, Callable[[RobotSummary], str]]] = [
        ("anchors (mean / end)", lambda r: f"{_num(r['anchors_mean'], 1)} / {r['anchors_end']}"),
        ("objects matched at end", lambda r: f"{r['matched_end']}/{r['true_objects_end']}"),
        ("MOTA / IDF1", lambda r: f"{_num(r['mota'], 3)} / {_num(r['idf1'], 3)}"),
        (
            "false anchors (mean / over 10 s)",
            lambda r: f"{_num(r['false_anchors_mean'], 1)} / {r['false_anchors_long']}",
        ),
        ("ground position error (median)", lambda r: _m(r["ground_error_m_median"])),
        ("peer position error (median)", lambda r: _m(r["peer_position_error_m_median"])),
        ("peer heading error (median)", lambda r: _rad(r["peer_heading_error_rad_median"])),
        ("frames with a peer pose", lambda r: r["peer_pose_frames"]),
        (
            "pointing games (success/played)",
            lambda r: f"{r['pointing_success']}/{r['pointing_games']}",
        ),
        (
            "guessing games (success/played)",
            lambda r: f"{r['guessing_success']}/{r['guessing_games']}",
        ),
        ("guessing success, later half", lambda r: _num(r["guessing_success_late"], 2)),
        ("lexicon: words / categories", lambda r: f"{r['lexicon_size']} / {r['categories']}"),
        ("frame rate (fps)", lambda r: _num(r["fps_mean"], 1)),
        ("CPU (cores)", lambda r: _num(r["cpu_cores_mean"], 2)),
        (
            "  of it the perception thread",
            lambda r: _num(r["cpu_cores_by_thread"].get("perception"), 2),
        ),
        ("resident memory (MB)", lambda r: _num(r["rss_mb_max"], 1)),
    ]
    robots = summary["robots"]
    print(f"{'':34}" + "".join(f"{'robot ' + r:>18}" for r in robots))
    for label, cell in rows:
        print(f"{label:34}" + "".join(f"{cell(v):>18}" for v in robots.values()))
    diff = summary["scaled_feature_difference"]
    print(
        f"scaled-feature difference between the robots (width, height, colour; mean over "
        f"{diff['objects_seen_by_both']} objects seen by both): "
        f"{_num(diff['mean_shared_features'], 4)}"
    )
    print(f"guessing games a minute (both robots): {summary['guessing_games_per_minute']:.1f}")


def _num(v: float | None, digits: int) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def _m(v: float | None) -> str:
    return "-" if v is None else f"{v * 100:.1f} cm"


def _rad(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f} rad"


def _figure(
    path: Path,
    robots: list[str],
    final: Mapping[str, _End],
    poses: Mapping[str, sc.Pose2],
    diffs: Mapping[int, Mapping[str, float]],
) -> None:
    """Fig. 5.5: per robot the map and the camera image with anchors; the feature table."""
    rows_images = []
    for robot in robots:
        end, _, truth, last, false = final[robot]
        marks = []
        for t in truth:
            x, y = sc.to_robot(poses[robot], t.x, t.y)
            bgr = (t.rgb[2], t.rgb[1], t.rgb[0])
            marks.append(MapMark(x, y, bgr, radius=max(t.size[:2]) / 2))
        for other in robots:
            if other != robot:
                x, y, th = sc.relative_pose(poses[robot], poses[other])
                marks.append(MapMark(x, y, (150, 150, 150), theta=th))
        m = caption(
            draw_map(end, 300, marks, false=false), f"robot {robot}: map (see the key below)"
        )
        parts = [m]
        if last is not None:
            cam = last.image if end is None else draw_anchors(last.image, end, false)
            parts.append(caption(cam, f"robot {robot}: camera"))
        rows_images.append(stack(parts, 1))
    header = ["object", "feature"] + [c for r in robots for c in (r, f"{r} scaled")] + ["diff"]
    rows, colours = [], []
    for tid, d in sorted(diffs.items()):
        objs = {r: next(o for o, t, _ in final[r].matched if t.id == tid) for r in robots}
        label = next(t.label for _, t, _ in final[robots[0]].matched if t.id == tid)
        ids = " ".join(f"{r}:{objs[r].id}" for r in robots)  # the anchors in the images
        for i, f in enumerate(sc.FEATURES):
            cells = [label if i == 0 else ids if i == 1 else "", f]
            for r in robots:
                raw, scl = objs[r].features.get(f), objs[r].scaled.get(f)
                cells += [
                    "-" if raw is None else f"{raw:.2f}",
                    "-" if scl is None else f"{scl:.2f}",
                ]
            cells.append("-" if f not in d else f"{d[f]:.2f}")
            rows.append(cells)
            colours.append(object_bgr(objs[robots[0]].features) if i == 0 else None)
    widths = [110, 90] + [70] * (2 * len(robots)) + [50]
    table = draw_table(header, rows, widths, colours)
    for line in reversed(FIGURE_KEY):
        table = caption(table, line)
    cv2.imwrite(str(path), stack([*rows_images, table], 0))


FIGURE_KEY = (
    "Map (x forward = up): discs = perceived objects (diameter = width),",
    "thick rings = objects remembered out of sight,",
    "red crosses = false anchors: near no true object (also in the image),",
    "brown squares = boxes, black arrows = the robot and the peers it sees;",
    "rings = true objects, grey arrow = the peer's true pose.",
    "Table: x, y, width, height in metres (the robot's ground frame);",
    "luminance, green_red, yellow_blue = mean Y, Cr, Cb (0-255);",
    "scaled = mapped to 0-1 by the experiment's statistics;",
    "diff = |a scaled - b scaled|.",
)
"""The figure's key: what the map's marks are and the table's units."""
