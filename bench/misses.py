"""Why objects are missed: every true box of a robustness run that no anchor box comes near
(the *misses* of ``percept.perception.evaluation.error_classes``), sorted by what the
simulator's truth says of the object at that frame.

The scorer's pairing decides what a miss is (no anchor box at IoU above 0.1); this script only
says why, in this order:

- *inside an anchor box*: over half the true box lies inside one bigger anchor box, so the
  object was seen but given to a neighbour's anchor; split by whether a touching object is of
  the same colour (every channel within ``SAME``), the object is mostly hidden (under ``HIDDEN``
  of it shows) or neither (touching objects of different colours);
- *no box near*: the object's colour is the floor's (every channel within ``FLOOR`` of the
  scene's ``[floor] color``), it is cut by the image border, mostly hidden, dark (no channel
  above ``DARK``), or none of these.

    python bench/misses.py --out OUT --sequences SEQS [--json FILE]

``OUT`` is a ``bench/robustness.py --out`` folder (its ``results/``, ``tracks/`` and
``scenes/``), ``SEQS`` the rendered sequences it tracked (``--keep --sequences``).
"""

from __future__ import annotations

import argparse
import configparser
import json
import sys
import tomllib
from collections import Counter
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from percept.perception.evaluation.error_classes import NEAR  # noqa: E402
from percept.perception.evaluation.tracking import (  # noqa: E402
    clip_boxes,
    iou,
    iou_pairs,
    read_mot,
    split_gt,
)

FLOOR = 45
"""Largest channel difference (0-255) from the floor's colour of a floor-like object."""
SAME = 30
"""Largest channel difference of two objects of one colour."""
HIDDEN = 0.6
"""Share of an object's pixels that show, under which it is mostly hidden."""
DARK = 60
"""Brightest channel of a dark object."""
INSIDE = 0.5
"""Share of a true box inside one anchor box from which the object was given to that anchor."""

CLASSES = (
    "inside an anchor box, touching an object of its colour",
    "inside an anchor box, mostly hidden",
    "inside an anchor box, touching objects of other colours",
    "no box near, floor-like colour",
    "no box near, cut by the image border",
    "no box near, mostly hidden",
    "no box near, dark",
    "no box near, other",
)


def covered(box: np.ndarray, anchors: np.ndarray) -> float:
    """The largest share of ``box`` (left, top, width, height) inside one of ``anchors``."""
    if not len(anchors):
        return 0.0
    x0 = np.maximum(box[0], anchors[:, 0])
    y0 = np.maximum(box[1], anchors[:, 1])
    x1 = np.minimum(box[0] + box[2], anchors[:, 0] + anchors[:, 2])
    y1 = np.minimum(box[1] + box[3], anchors[:, 1] + anchors[:, 3])
    inter = np.clip(x1 - x0, 0, None) * np.clip(y1 - y0, 0, None)
    return float(inter.max() / max(box[2] * box[3], 1.0))


def touching(boxes: np.ndarray, i: int) -> list[int]:
    """Indices of the boxes other than ``i`` that overlap or touch box ``i``."""
    b = boxes[i]
    return [
        j
        for j, o in enumerate(boxes)
        if j != i
        and o[0] <= b[0] + b[2]
        and b[0] <= o[0] + o[2]
        and o[1] <= b[1] + b[3]
        and b[1] <= o[1] + o[3]
    ]


def classify(
    i: int,
    boxes: np.ndarray,
    colours: list[np.ndarray],
    anchors: np.ndarray,
    floor: np.ndarray,
    truth: dict[str, object],
) -> str:
    """The class of missed true box ``i`` of a frame (``boxes`` its true boxes, ``colours``
    their objects' RGB, ``truth`` the object's record in ``truth.jsonl``)."""
    colour = colours[i]
    visible = float(truth["visible"])  # type: ignore[arg-type]  # a number in truth.jsonl
    if covered(boxes[i], anchors) > INSIDE:
        if any(np.abs(colours[j] - colour).max() < SAME for j in touching(boxes, i)):
            return CLASSES[0]
        return CLASSES[1] if visible < HIDDEN else CLASSES[2]
    if np.abs(colour - floor).max() < FLOOR:
        return CLASSES[3]
    if truth["bbox"] != truth["bbox_full"]:
        return CLASSES[4]
    if visible < HIDDEN:
        return CLASSES[5]
    return CLASSES[6] if colour.max() < DARK else CLASSES[7]


def pair_misses(scene_file: Path, seq: Path, tracks: Path) -> Counter[tuple[str, str]]:
    """Missed true boxes of one (scene, robot) pair, counted by (class, object name)."""
    scene = tomllib.loads(scene_file.read_text(encoding="utf-8"))
    floor = np.array(scene["floor"]["color"], float)
    names = {o["id"]: o["name"] for o in scene["objects"]}
    info = configparser.ConfigParser()
    info.read(seq / "seqinfo.ini")
    size = (int(info["Sequence"]["imWidth"]), int(info["Sequence"]["imHeight"]))
    truth: dict[int, dict[int, dict[str, object]]] = {}
    for line in (seq / "truth.jsonl").read_text(encoding="utf-8").splitlines():
        record = json.loads(line)
        truth[record["frame"]] = {o["id"]: o for o in record["objects"]}
    scored, _ = split_gt(read_mot(seq / "gt" / "gt.txt"))
    hyp = read_mot(tracks)
    counts: Counter[tuple[str, str]] = Counter()
    for f in sorted(set(scored[:, 0].astype(int))):
        rows = scored[scored[:, 0] == f]
        boxes = clip_boxes(rows[:, 2:6], size)
        ids = rows[:, 1].astype(int).tolist()
        anchors = hyp[hyp[:, 0] == f][:, 2:6]
        s = iou(boxes, anchors) if len(anchors) else np.zeros((len(boxes), 0))
        paired = {r for r, _ in iou_pairs(s, 0.5)}
        colours = [np.array(truth[f][k]["color"], float) for k in ids]
        for i, k in enumerate(ids):
            if i in paired or (s.shape[1] and s[i].max() > NEAR):
                continue
            cls = classify(i, boxes, colours, anchors, floor, truth[f][k])
            counts[cls, names[k]] += 1
    return counts


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="bench/robustness.py output folder")
    p.add_argument("--sequences", type=Path, required=True, help="the rendered sequences")
    p.add_argument("--json", type=Path, help="write the counts per pair here")
    args = p.parse_args(argv)
    total: Counter[str] = Counter()
    worst: dict[str, Counter[str]] = {c: Counter() for c in CLASSES}
    per_pair: dict[str, dict[str, int]] = {}
    for result in sorted((args.out / "results").glob("*.json")):
        r = json.loads(result.read_text(encoding="utf-8"))
        name = f"{r['scene']}-{r['robot']}"
        counts = pair_misses(
            args.out / "scenes" / f"{r['scene']}.toml",
            args.sequences / name,
            args.out / "tracks" / f"{name}.txt",
        )
        by_class: Counter[str] = Counter()
        for (cls, obj), n in counts.items():
            by_class[cls] += n
            worst[cls][f"{name} {obj}"] += n
        total.update(by_class)
        per_pair[name] = dict(by_class)
    misses = sum(total.values())
    print(f"missed true boxes: {misses}")
    for cls in CLASSES:
        share = total[cls] / misses if misses else 0.0
        most = ", ".join(f"{k} ({n})" for k, n in worst[cls].most_common(3))
        print(f"{total[cls]:6d} {share:6.1%}  {cls}: {most}")
    if args.json:
        args.json.write_text(json.dumps(per_pair, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
