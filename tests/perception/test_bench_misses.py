"""bench/misses.py: every missed true box of a robustness run named by the simulator's truth
(inside a bigger anchor box, or no box near and why)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[2]

FLOOR = [150, 150, 145]
OBJECTS = {
    1: ("red-cuboid", [200, 30, 35]),
    2: ("red-cone", [205, 35, 30]),  # beside 1, inside 1's anchor box: same colour
    3: ("grey-toy", [140, 150, 150]),  # alone, no box: floor-like
    4: ("blue-ball", [30, 70, 200]),  # alone, no box, cut by the border
    5: ("green-block", [40, 160, 60]),  # paired with an anchor: not a miss
}
# frame 1's true boxes (left, top, width, height) and what the truth says of each
BOXES = {1: (100, 100, 60, 60), 2: (160, 140, 12, 12), 3: (20, 20, 15, 15), 4: (0, 150, 10, 20),
         5: (250, 20, 30, 30)}  # fmt: skip
ANCHORS = [(100, 100, 75, 60), (251, 20, 30, 30)]


def misses_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_misses", REPO / "bench" / "misses.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def write_run(root: Path) -> tuple[Path, Path]:
    out, seqs = root / "run", root / "seqs"
    (out / "results").mkdir(parents=True)
    (out / "tracks").mkdir()
    (out / "scenes").mkdir()
    seq = seqs / "room-0001-a"
    (seq / "gt").mkdir(parents=True)
    objects = "".join(
        f'[[objects]]\nid = {k}\nname = "{name}"\ncolor = {colour}\n'
        for k, (name, colour) in OBJECTS.items()
    )
    (out / "scenes" / "room-0001.toml").write_text(
        f"[floor]\ncolor = {FLOOR}\n{objects}", encoding="utf-8"
    )
    (seq / "seqinfo.ini").write_text("[Sequence]\nimWidth=320\nimHeight=200\n", encoding="utf-8")
    (seq / "gt" / "gt.txt").write_text(
        "".join(f"1,{k},{x},{y},{w},{h},1,-1,-1,-1\n" for k, (x, y, w, h) in BOXES.items()),
        encoding="utf-8",
    )
    truth = [
        {
            "id": k,
            "color": colour,
            "visible": 1.0,
            "bbox": list(BOXES[k]),
            "bbox_full": [-10, 150, 20, 20] if k == 4 else list(BOXES[k]),
        }
        for k, (_, colour) in OBJECTS.items()
    ]
    (seq / "truth.jsonl").write_text(
        json.dumps({"frame": 1, "objects": truth}) + "\n", encoding="utf-8"
    )
    (out / "tracks" / "room-0001-a.txt").write_text(
        "".join(f"1,{n},{x},{y},{w},{h},1,-1,-1,-1\n" for n, (x, y, w, h) in enumerate(ANCHORS)),
        encoding="utf-8",
    )
    (out / "results" / "room-0001-a.json").write_text(
        json.dumps({"scene": "room-0001", "robot": "a"}), encoding="utf-8"
    )
    return out, seqs


def test_each_missed_box_is_named_by_the_truth(tmp_path: Path) -> None:
    bench = misses_module()
    out, seqs = write_run(tmp_path)
    report = tmp_path / "misses.json"
    assert bench.main(["--out", str(out), "--sequences", str(seqs), "--json", str(report)]) == 0
    # object 1 is paired with the first anchor (IoU 0.8) and object 5 with the second
    assert json.loads(report.read_text(encoding="utf-8")) == {
        "room-0001-a": {
            "inside an anchor box, touching an object of its colour": 1,
            "no box near, floor-like colour": 1,
            "no box near, cut by the image border": 1,
        }
    }
