"""Scoring (MOT CLEAR/IDF1, CDnet) on hand-made data with hand-computed values, against
py-motmetrics on random data, and the offline commands end to end on a synthetic sequence."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from percept.perception.evaluation.foreground import frame_counts, pooled
from percept.perception.evaluation.synthetic import Blob, SyntheticScene
from percept.perception.evaluation.tracking import (
    evaluate_tracking,
    ignoring,
    iou,
    mot_box,
    read_mot,
)
from percept.runtime.cli import main

pytestmark = pytest.mark.timeout(60)


def rows(*boxes: tuple) -> np.ndarray:
    """MOT15 rows from (frame, id, left, top, width, height[, conf])."""
    out = []
    for b in boxes:
        conf = b[6] if len(b) > 6 else 1
        out.append([*b[:6], conf, -1, -1, -1])
    return np.array(out, float)


# Two objects over four frames; the hypotheses miss twice, add two false boxes and switch the
# identity of object 1 once. Hand-computed: MOTA = 1 - (2 + 2 + 1) / 8 = 0.375; identity
# pairs g1-h10 (2 frames), g1-h11 (2), g2-h20 (2) -> IDTP = 4, IDF1 = 2 * 4 / (8 + 8) = 0.5.
GT = rows(
    *[(f, 1, 0, 0, 10, 10) for f in range(1, 5)],
    *[(f, 2, 50, 50, 10, 10) for f in range(1, 5)],
)
HYP = rows(
    (1, 10, 0, 0, 10, 10),
    (1, 20, 50, 50, 10, 10),
    (2, 10, 1, 0, 10, 10),  # IoU 90/110
    (2, 30, 100, 100, 10, 10),  # false positive; object 2 missed
    (3, 11, 0, 0, 10, 10),  # identity switch for object 1
    (3, 20, 50, 50, 10, 10),
    (4, 11, 0, 0, 10, 10),
    (4, 20, 55, 50, 10, 10),  # IoU 1/3: a miss and a false positive
)


def test_clear_mot_and_idf1_by_hand() -> None:
    s = evaluate_tracking(GT, HYP)
    assert (s.fn, s.fp, s.id_switches, s.matches, s.gt_boxes) == (2, 2, 1, 6, 8)
    assert s.mota == pytest.approx(0.375)
    assert s.idf1 == pytest.approx(0.5)
    assert (s.idp, s.idr) == (pytest.approx(0.5), pytest.approx(0.5))
    assert s.motp == pytest.approx((5 + 90 / 110) / 6)


def test_ignored_ground_truth_removes_the_hypotheses_on_it() -> None:
    zero_marked = np.concatenate([GT, rows((2, 9, 100, 100, 10, 10, 0))])
    s = evaluate_tracking(zero_marked, HYP)
    assert (s.fp, s.gt_boxes, s.hypothesis_boxes) == (1, 8, 7)
    assert s.mota == pytest.approx(1 - (2 + 1 + 1) / 8)
    assert s.idf1 == pytest.approx(2 * 4 / (8 + 7))
    # MOT16 layout (conf, class, visibility): a static person (7) is a distractor like conf 0;
    # a car (3) is simply not scored, so a box on it stays a false positive.
    mot16 = np.column_stack([GT[:, :7], np.ones(len(GT)), np.ones(len(GT))])
    for cls, fp in ((7, 1), (3, 2)):
        extra = np.array([[2, 9, 100, 100, 10, 10, 1, cls, 1.0]])
        assert evaluate_tracking(np.concatenate([mot16, extra]), HYP).fp == fp


def test_an_object_ignored_is_neither_missed_nor_a_false_box() -> None:
    # object 2 ignored: its miss in frame 2 goes, and so do the boxes that pair with it (frames 1
    # and 3); frame 4's box at IoU 1/3 pairs with nothing and stays a false box, as does frame 2's
    s = evaluate_tracking(ignoring(GT, [2]), HYP)
    assert (s.gt_boxes, s.fn, s.fp, s.id_switches, s.matches) == (4, 0, 2, 1, 4)
    assert s.mota == pytest.approx(1 - (0 + 2 + 1) / 4)
    assert ignoring(GT, [2])[:, 6].tolist() == [0 if i == 2 else 1 for i in GT[:, 1]]
    assert GT[:, 6].min() == 1  # the input is not changed
    assert evaluate_tracking(ignoring(GT, []), HYP) == evaluate_tracking(GT, HYP)


def test_ground_truth_is_clipped_to_the_image() -> None:
    gt = rows((1, 1, -12, 0, 22, 10))  # starts left of the image
    hyp = rows((1, 1, 0, 0, 10, 10))
    assert evaluate_tracking(gt, hyp).matches == 0  # IoU 100 / 220 with the unclipped box
    assert evaluate_tracking(gt, hyp, image_size=(64, 48)).matches == 1


def test_agrees_with_py_motmetrics_on_random_tracks() -> None:
    mm = pytest.importorskip("motmetrics")
    rng = np.random.default_rng(7)
    gt, hyp = [], []
    for obj in range(6):
        x, y = rng.uniform(0, 200, 2)
        for f in range(1, 41):
            x, y = x + rng.normal(2, 1), y + rng.normal(0, 1)
            if rng.random() < 0.9:
                gt.append((f, obj + 1, x, y, 20, 30))
            if rng.random() < 0.85:
                hid = 100 + obj + 10 * (f > 20 and obj % 3 == 0)
                hyp.append((f, hid, x + rng.normal(0, 3), y + rng.normal(0, 3), 20, 30))
        for f in rng.integers(1, 41, 3):
            hyp.append((f, 900 + obj, *rng.uniform(0, 250, 2), 20, 30))
    gt_rows, hyp_rows = rows(*gt), rows(*hyp)
    ours = evaluate_tracking(gt_rows, hyp_rows)
    acc = mm.MOTAccumulator(auto_id=False)
    for f in range(1, 41):
        g, h = gt_rows[gt_rows[:, 0] == f], hyp_rows[hyp_rows[:, 0] == f]
        overlap = iou(g[:, 2:6], h[:, 2:6])
        acc.update(
            g[:, 1].astype(int),
            h[:, 1].astype(int),
            np.where(overlap >= 0.5, 1 - overlap, np.nan),
            frameid=f,
        )
    theirs = mm.metrics.create().compute(
        acc, metrics=["mota", "idf1", "num_switches", "num_false_positives", "num_misses"]
    )
    assert ours.id_switches == int(theirs["num_switches"].iloc[0])
    assert ours.fp == int(theirs["num_false_positives"].iloc[0])
    assert ours.fn == int(theirs["num_misses"].iloc[0])
    assert ours.mota == pytest.approx(float(theirs["mota"].iloc[0]))
    assert ours.idf1 == pytest.approx(float(theirs["idf1"].iloc[0]))


def test_cdnet_scoring_honours_85_170_and_50() -> None:
    gt = np.array([[255, 255, 0, 50], [85, 170, 255, 0]], np.uint8)
    mask = np.array([[255, 0, 255, 255], [255, 255, 0, 0]], np.uint8)
    # 85 and 170 not scored; 50 (shadow) is a negative, so foreground there is a false positive.
    assert frame_counts(gt, mask) == (1, 2, 2, 1)
    s = pooled([frame_counts(gt, mask)] * 3)
    assert (s.tp, s.fp, s.fn, s.tn, s.frames) == (3, 6, 6, 3, 3)
    assert (s.precision, s.recall, s.f1) == (pytest.approx(1 / 3),) * 3
    roi = np.array([[255, 255, 255, 0]] * 2, np.uint8)
    r = pooled([frame_counts(gt, mask, roi)])
    assert (r.tp, r.fp, r.fn, r.tn) == (1, 1, 2, 0)
    assert r.f1 == pytest.approx(2 * 0.5 * (1 / 3) / (0.5 + 1 / 3))


def _sequence(folder: Path, mot: bool) -> SyntheticScene:
    """40 frames of two objects appearing after 10 empty frames; gt.txt beside them."""
    red = Blob((40, 40, 220), (0.12, 0.15), ((12, 0.3, 0.4), (40, 0.3, 0.4)))
    keys = ((14, 0.6, 0.6), (20, 0.6, 0.6), (40, 0.8, 0.5))
    scene = SyntheticScene(176, 144, [red, Blob((40, 190, 40), (0.1, 0.12), keys)])
    images = folder / "img1" if mot else folder
    images.mkdir(parents=True)
    lines = []
    for f in range(40):
        cv2.imwrite(str(images / f"{f + 1:06d}.png"), scene.render(f))
        truth = [(i, *mot_box(box)) for i, *box in scene.truth(f)]
        lines += [f"{f + 1},{i},{x},{y},{w},{h},1,-1,-1,-1" for i, x, y, w, h in truth]
    (folder / "gt").mkdir()
    (folder / "gt" / "gt.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    if mot:
        (folder / "seqinfo.ini").write_text(
            "[Sequence]\nname=synthetic\nimDir=img1\nframeRate=25\nseqLength=40\n"
            "imWidth=176\nimHeight=144\nimExt=.png\n",
            encoding="utf-8",
        )
    return scene


def _json(capsys) -> dict:
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


@pytest.mark.parametrize("mot", [True, False], ids=["mot-folder", "image-folder"])
def test_track_then_eval_tracking(tmp_path, capsys, mot) -> None:
    _sequence(tmp_path / "seq", mot)
    tracks = tmp_path / "tracks.txt"
    args = ["track", str(tmp_path / "seq"), "--calibration-frames", "10", "--out", str(tracks)]
    assert main(args) == 0
    summary = _json(capsys)
    assert (
        summary["frames"] == 40
        and summary["ms_per_frame_p90"] >= summary["ms_per_frame_median"] > 0
    )
    written = read_mot(tracks)
    assert written.shape[1] == 10 and written[:, 0].min() >= 13 and set(written[:, 1]) == {1, 2}
    gt = tmp_path / "seq" / "gt" / "gt.txt"
    assert main(["eval", "tracking", "--gt", str(gt), "--tracks", str(tracks)]) == 0
    scores = _json(capsys)
    assert scores["id_switches"] == 0 and scores["mota"] > 0.85 and scores["idf1"] > 0.9
    assert scores["clip_to"] == ([176, 144] if mot else None)


def test_foreground_then_eval_foreground(tmp_path, capsys) -> None:
    scene = _sequence(tmp_path / "seq", mot=False)
    masks, gt = tmp_path / "masks", tmp_path / "groundtruth"
    gt.mkdir()
    for f in range(40):
        label = np.zeros((144, 176), np.uint8)
        for _, x, y, w, h in scene.truth(f):
            label[y : y + h, x : x + w] = 255
        edge = cv2.morphologyEx(label, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8))
        label[edge > 0] = 170  # object borders are not scored in CDnet
        cv2.imwrite(str(gt / f"gt{f + 1:06d}.png"), label)
    (tmp_path / "temporalROI.txt").write_text("11 40\n", encoding="utf-8")
    command = [
        "foreground",
        str(tmp_path / "seq"),
        "--calibration-frames",
        "10",
        "--out",
        str(masks),
    ]
    assert main(command) == 0
    assert sorted(p.name for p in masks.iterdir())[:2] == ["000001.png", "000002.png"]
    assert set(np.unique(cv2.imread(str(masks / "000030.png"), cv2.IMREAD_GRAYSCALE))) == {0, 255}
    capsys.readouterr()
    assert main(["eval", "foreground", "--gt", str(gt), "--masks", str(masks)]) == 0
    scores = _json(capsys)
    assert scores["temporal_roi"] == [11, 40] and scores["frames"] == 30 and scores["roi"] is None
    assert scores["f1"] > 0.95
