"""bench/robustness.py: the objects of the floor's colour, and the distribution with them
ignored."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from percept.config.loader import load
from percept.drivers.sim.scenarios.draw import FLOOR_LIKE
from percept.drivers.sim.scene import Scene

REPO = Path(__file__).resolve().parents[2]
FLOOR = [150, 150, 145]


def robustness_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "bench_robustness", REPO / "bench" / "robustness.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # (its dataclasses look their module up there)
    spec.loader.exec_module(module)
    return module


def scene(tmp_path: Path, colours: dict[int, list[int]]) -> Scene:
    """A scene as the scene loader reads it from its file: one robot, a block of each colour."""
    objects = "".join(
        f'[[objects]]\nid = {k}\nname = "block-{k}"\nshape = "block"\nsize = [0.1, 0.1, 0.1]\n'
        f"color = {c}\npose = [0.0, {0.2 * k}, 0.0]\n"
        for k, c in colours.items()
    )
    robot = '[[robots]]\nname = "a"\nprofile = "robotis-op3"\npose = [-0.7, 0.0, 0.0]\n'
    file = tmp_path / "room-0001.toml"
    file.write_text(
        f'name = "room-0001"\n[floor]\ncolor = {FLOOR}\n{robot}{objects}', encoding="utf-8"
    )
    return load(Scene, file)


def rows(*boxes: tuple[int, int, int, int, int, int]) -> np.ndarray:
    return np.array([[*b, 1, -1, -1, -1] for b in boxes], float)


def test_floor_like_is_every_channel_within_the_generators_range(tmp_path: Path) -> None:
    bench = robustness_module()
    edge = [c + FLOOR_LIKE for c in FLOOR]
    beyond = [FLOOR[0] + FLOOR_LIKE + 1, *FLOOR[1:]]
    room = scene(tmp_path, {1: [200, 30, 35], 2: edge, 3: beyond, 4: [140, 145, 150]})
    assert bench.floor_like(room) == [2, 4]


def test_floor_like_share_and_mota_with_them_ignored(tmp_path: Path) -> None:
    bench = robustness_module()
    room = scene(tmp_path, {1: [200, 30, 35], 2: FLOOR})
    # object 1 found in both frames; object 2 (the floor's colour) missed but for an anchor on
    # its lit top in frame 1 (IoU 0.4: no pair, a false box when it is counted)
    gt = rows(
        (1, 1, 0, 0, 20, 20), (1, 2, 50, 50, 20, 20), (2, 1, 0, 0, 20, 20), (2, 2, 50, 50, 20, 20)
    )
    top = (1, 8, 50, 50, 20, 8)
    hyp = rows((1, 7, 0, 0, 20, 20), top, (2, 7, 1, 0, 20, 20))
    share, mota = bench.floor_like_scores(room, gt, hyp, (320, 200))
    assert share == 0.5
    assert mota == 1.0  # against 1 - (2 + 1) / 4 with object 2 counted
    assert len(bench.off(gt, hyp, [2], (320, 200))) == 2
    # an anchor box mostly off it stays, and so does one inside it that pairs with an object
    # counted (object 3 before object 2)
    front = np.concatenate([gt, rows((1, 3, 52, 52, 16, 16))])
    kept = rows((1, 9, 0, 0, 70, 70), (1, 10, 52, 52, 16, 15))
    assert len(bench.off(front, kept, [2], (320, 200))) == 2
    only = gt[gt[:, 1] == 2]
    assert bench.floor_like_scores(room, only, hyp, (320, 200)) == (1.0, None)


ERRORS = {"boxes": 100, "matched": 90, "misses": 10, "false_boxes": 0, "merged": 0, "too_big": 0,
          "on_a_part": 0, "cut": 0}  # fmt: skip


def result(bench: ModuleType, mota: float, share: float | None, ignored: float | None) -> object:
    return bench.Result(
        scene="room-0001", file="f", robot="a", frames=10, mota=mota, idf1=mota,
        anchors_per_object=1.0, persistent_false_anchors=0, longest_false_seconds=0.0,
        seconds=1.0, errors=dict(ERRORS), floor_like_share=share,
        mota_floor_like_ignored=ignored,
    )  # fmt: skip


def test_summary_counts_the_pairs_they_cap_and_leaves_out_the_uncounted() -> None:
    bench = robustness_module()
    results = [
        result(bench, 0.95, 0.0, 0.95),
        result(bench, 0.85, 0.15, 0.99),  # at most 0.85 with every such box missed
        result(bench, 0.30, 1.0, None),  # sees only such an object: no MOTA without it
        result(bench, 0.70, None, None),  # written before they were counted
    ]
    floor = bench.floor_like_summary(results)
    assert floor["pairs_counted"] == 3
    assert floor["pairs_with_one"] == 2
    assert floor["pairs_with_only_those"] == 1
    assert floor["share_of_true_boxes"] == pytest.approx((0.15 + 1.0) / 3, abs=1e-4)
    assert floor["pairs_whose_ceiling_is_below"] == {"0.97": 2, "0.90": 2, "0.80": 1}
    assert floor["mota_ignored_median"] == pytest.approx(0.97)
    assert floor["mota_ignored_min"] == 0.95
    assert bench.floor_like_summary(results[3:]) == {"pairs_counted": 0}
    assert "floor's colour" in bench.table(results, bench.summarise(results))
    assert math.isfinite(bench.summarise(results)["mota_median"])
    # the figure marks the one pair with such an object and a MOTA without it (0.99, the pair
    # of MOTA 0.85, third of the four bars sorted), and nothing else
    plain = [dataclasses.replace(r, mota_floor_like_ignored=None) for r in results]
    changed = np.any(bench.figure(results, 0.8, 0.4) != bench.figure(plain, 0.8, 0.4), axis=2)
    rows, cols = np.nonzero(changed)
    assert len(rows) and cols.min() >= 50 + 2 * 200 and cols.max() < 50 + 3 * 200
