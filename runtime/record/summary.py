"""The demo's summary: each robot's recording scored against the simulated truth, printed as a
table, written as ``summary.json`` and drawn as the chapter's Fig. 5.5 (``figure.png``)."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import cv2

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

log = logging.getLogger("percept.summary")

SAMPLE_EVERY = 10  # score every n-th world model (truth costs a little)


def _read(path: Path) -> tuple[list[dict], list[dict], Any]:
    from percept.runtime.record.reader import Recording, read_recording

    worlds, statuses, last = [], [], None
    for kind, item in read_recording(path, Recording(path)):
        if kind == "world":
            worlds.append(item)
        elif kind == "status":
            statuses.append(item)
        elif kind == "frame":
            last = item
    return worlds, statuses, last


def summarise(
    options: Any, records: dict[str, Path], epoch: float, events: list[dict]
) -> dict[str, Any]:
    from percept.runtime.settings.scene import open_world

    world = open_world(options.scene)
    robots = list(records)
    data = {r: _read(path) for r, path in records.items()}
    poses = {r: tuple(world.scene.robot(r).pose) for r in robots}
    per_robot: dict[str, dict[str, Any]] = {}
    final: dict[str, Any] = {}
    for robot in robots:
        worlds, statuses, last = data[robot]
        other = next((r for r in robots if r != robot), None)
        errors, peer_pos, peer_head, anchors = [], [], [], []
        for w in worlds[::SAMPLE_EVERY]:
            truth = _truth(world, w["stamp"] - epoch)
            matches = sc.match(w, truth, poses[robot])
            errors += [d for _, _, d in matches]
            anchors.append(len(w["objects"]))
            if other is not None:
                err = sc.peer_error(w, other, sc.relative_pose(poses[robot], poses[other]))
                if err is not None:
                    peer_pos.append(err[0])
                    peer_head.append(err[1])
        end = worlds[-1] if worlds else {"objects": [], "boxes": [], "peers": {}}
        truth_end = _truth(world, end.get("stamp", epoch) - epoch)
        final[robot] = (end, sc.match(end, truth_end, poses[robot]), truth_end, last)
        games = (statuses[-1].get("games") if statuses else None) or {}
        per_robot[robot] = {
            "world_models": len(worlds),
            "anchors_mean": sc.mean(anchors),
            "anchors_end": len(end["objects"]),
            "true_objects_end": len(truth_end),
            "matched_end": len(final[robot][1]),
            "ground_error_m_median": sc.median(errors),
            "peer_position_error_m_median": sc.median(peer_pos),
            "peer_heading_error_rad_median": sc.median(peer_head),
            "peer_pose_frames": f"{len(peer_pos)}/{len(worlds[::SAMPLE_EVERY])}",
            "pointing_games": games.get("played", 0),
            "pointing_success": games.get("success", 0),
            "fps_mean": sc.mean([s["fps"] for s in statuses[2:]]),
            "cpu_cores_mean": sc.mean([s.get("cpu") for s in statuses[2:]]),
            "rss_mb_max": max((s.get("rss_mb") or 0 for s in statuses), default=None),
        }
    world.close()
    diffs = sc.scaled_differences({r: final[r][1] for r in robots}) if len(robots) > 1 else {}
    shared = [d[f] for d in diffs.values() for f in sc.SHARED if f in d]
    summary = {
        "scene": str(options.scene),
        "robots": per_robot,
        "scaled_feature_difference": {
            "objects_seen_by_both": len(diffs),
            "mean_shared_features": sc.mean(shared),
            "per_object": {
                str(k): {f: round(v, 4) for f, v in d.items()} for k, d in diffs.items()
            },
        },
        "joint_attention_events": sum(e.get("event") == "joint_attention" for e in events),
    }
    _print_table(summary)
    _figure(options.out / "figure.png", robots, final, poses, diffs)
    return summary


def _truth(world: Any, t: float) -> list[sc.TruthObject]:
    truth = world.truth(max(0.0, t), views=[])
    return [
        sc.TruthObject(o.id, o.name, float(o.position[0]), float(o.position[1]), o.size, o.color)
        for o in truth.objects.values()
    ]


def _print_table(summary: dict[str, Any]) -> None:
    rows = [
        ("anchors (mean / end)", lambda r: f"{_num(r['anchors_mean'], 1)} / {r['anchors_end']}"),
        ("objects matched at end", lambda r: f"{r['matched_end']}/{r['true_objects_end']}"),
        ("ground position error (median)", lambda r: _m(r["ground_error_m_median"])),
        ("peer position error (median)", lambda r: _m(r["peer_position_error_m_median"])),
        ("peer heading error (median)", lambda r: _rad(r["peer_heading_error_rad_median"])),
        ("frames with a peer pose", lambda r: r["peer_pose_frames"]),
        (
            "pointing games (success/played)",
            lambda r: f"{r['pointing_success']}/{r['pointing_games']}",
        ),
        ("frame rate (fps)", lambda r: _num(r["fps_mean"], 1)),
        ("CPU (cores)", lambda r: _num(r["cpu_cores_mean"], 2)),
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


def _num(v: float | None, digits: int) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def _m(v: float | None) -> str:
    return "-" if v is None else f"{v * 100:.1f} cm"


def _rad(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f} rad"


def _figure(path: Path, robots, final, poses, diffs) -> None:
    """Fig. 5.5: per robot the map and the camera image with anchors; the feature table."""
    rows_images = []
    for robot in robots:
        end, _, truth, last = final[robot]
        marks = []
        for t in truth:
            x, y = sc.to_robot(poses[robot], t.x, t.y)
            bgr = (t.rgb[2], t.rgb[1], t.rgb[0])
            marks.append(MapMark(x, y, bgr, radius=max(t.size[:2]) / 2))
        for other in robots:
            if other != robot:
                x, y, th = sc.relative_pose(poses[robot], poses[other])
                marks.append(MapMark(x, y, (150, 150, 150), theta=th))
        m = caption(draw_map(end, 300, marks), f"robot {robot}: map (see the key below)")
        cam = draw_anchors(last.image, end) if last is not None else None
        parts = [m] if cam is None else [m, caption(cam, f"robot {robot}: camera")]
        rows_images.append(stack(parts, 1))
    header = ["object", "feature"] + [c for r in robots for c in (r, f"{r} scaled")] + ["diff"]
    rows, colours = [], []
    for tid, d in sorted(diffs.items()):
        objs = {r: next(o for o, t, _ in final[r][1] if t.id == tid) for r in robots}
        label = next(t.label for _, t, _ in final[robots[0]][1] if t.id == tid)
        ids = " ".join(f"{r}:{objs[r]['id']}" for r in robots)  # the anchors in the images
        for i, f in enumerate(sc.FEATURES):
            cells = [label if i == 0 else ids if i == 1 else "", f]
            for r in robots:
                raw, scl = objs[r]["features"].get(f), objs[r]["scaled"].get(f)
                cells += [
                    "-" if raw is None else f"{raw:.2f}",
                    "-" if scl is None else f"{scl:.2f}",
                ]
            cells.append("-" if f not in d else f"{d[f]:.2f}")
            rows.append(cells)
            colours.append(object_bgr(objs[robots[0]]["features"]) if i == 0 else None)
    widths = [110, 90] + [70] * (2 * len(robots)) + [50]
    table = draw_table(header, rows, widths, colours)
    for line in reversed(FIGURE_KEY):
        table = caption(table, line)
    cv2.imwrite(str(path), stack([*rows_images, table], 0))


FIGURE_KEY = (
    "Map (x forward = up): discs = perceived objects (diameter = width),",
    "brown squares = boxes, black arrows = the robot and the peers it sees;",
    "rings = true objects, grey arrow = the peer's true pose.",
    "Table: x, y, width, height in metres (the robot's ground frame);",
    "luminance, green_red, yellow_blue = mean Y, Cr, Cb (0-255);",
    "scaled = mapped to 0-1 by the experiment's statistics;",
    "diff = |a scaled - b scaled|.",
)
"""The figure's key: what the map's marks are and the table's units."""
