"""Tracking accuracy against MOTChallenge ground truth: CLEAR-MOT (MOTA) and IDF1.

Boxes match when their IoU is at least 0.5. Per frame, a ground-truth object keeps the
hypothesis it was matched to in the previous frame if they still match; the rest are paired by
the Hungarian method on 1 - IoU. An identity switch is counted when an object is matched to a
different hypothesis than the one it was last matched to (py-motmetrics' rule).
``MOTA = 1 - (FN + FP + IDSW) / GT``. IDF1 pairs whole trajectories one-to-one so as to maximise
the frames in which they match (Ristani et al. 2016): ``IDF1 = 2 IDTP / (GT + hypotheses)``.

MOTChallenge ignore rules: a ground-truth row with ``conf`` 0, or (MOT16 and later, 9 columns
with a class) of class 2, 7, 8 or 12 (person on vehicle, static person, distractor,
reflection), is not scored, and hypotheses that match it in its frame are removed before scoring;
rows of other non-pedestrian classes are dropped. Ground-truth boxes are clipped to the image
when its size is known (``seqinfo.ini``), since some MOT15 boxes start left of it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from percept.perception.assignment import linear_sum_assignment

DISTRACTOR_CLASSES = (2, 7, 8, 12)
PEDESTRIAN = 1


@dataclass(frozen=True)
class TrackingScores:
    """CLEAR-MOT and identity scores of one sequence."""

    mota: float
    motp: float
    """Mean IoU of the matched pairs."""
    idf1: float
    idp: float
    idr: float
    id_switches: int
    fp: int
    fn: int
    matches: int
    gt_boxes: int
    """Ground-truth boxes scored."""
    hypothesis_boxes: int
    """Hypothesis boxes scored (after removing those on ignored objects)."""
    frames: int
    gt_ids: int
    hypothesis_ids: int

    def as_dict(self) -> dict[str, object]:
        """Plain values for JSON, rounded to 4 decimals; an undefined score is None and
        ``undefined`` says why (JSON has no NaN)."""
        return json_scores(asdict(self), _UNDEFINED)


_UNDEFINED = {
    "mota": "no ground-truth boxes",
    "motp": "no matched boxes",
    "idf1": "no boxes at all",
    "idp": "no hypothesis boxes",
    "idr": "no ground-truth boxes",
}


def json_scores(scores: dict[str, Any], why: dict[str, str]) -> dict[str, object]:
    """``scores`` rounded to 4 decimals, NaN replaced by None, and (when any is) ``undefined``:
    the reason per score from ``why``."""
    out: dict[str, object] = {}
    undefined: dict[str, str] = {}
    for name, value in scores.items():
        if isinstance(value, float) and not math.isfinite(value):
            out[name] = None
            undefined[name] = why.get(name, "not defined for this input")
        else:
            out[name] = round(value, 4) if isinstance(value, float) else value
    if undefined:
        out["undefined"] = undefined
    return out


def mot_box(box: Sequence[float]) -> tuple[float, ...]:
    """The MOTChallenge box of an image box ``(left, top, width, height)``.

    Image boxes count pixels from 0 (OpenCV's), MOTChallenge's from 1 (the top-left pixel is
    (1, 1), as every ``gt.txt`` has it); every MOT row percept writes goes through here.
    """
    left, top, width, height = box
    return (left + 1, top + 1, width, height)


def read_mot(path: str | Path) -> np.ndarray:
    """Rows of a MOTChallenge file as floats (empty file: shape (0, 10))."""
    text = Path(path).read_text(encoding="utf-8").strip()
    if not text:
        return np.zeros((0, 10))
    rows = [[float(v) for v in line.split(",")] for line in text.splitlines() if line.strip()]
    width = max(len(r) for r in rows)
    return np.array([r + [-1.0] * (width - len(r)) for r in rows])


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) IoU of boxes (left, top, width, height)."""
    ax1, ay1 = a[:, 0:1] + a[:, 2:3], a[:, 1:2] + a[:, 3:4]
    bx1, by1 = b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]
    w = np.clip(np.minimum(ax1, bx1) - np.maximum(a[:, 0:1], b[:, 0]), 0, None)
    h = np.clip(np.minimum(ay1, by1) - np.maximum(a[:, 1:2], b[:, 1]), 0, None)
    inter = w * h
    union = a[:, 2:3] * a[:, 3:4] + b[:, 2] * b[:, 3] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1), 0.0)


def split_gt(gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(scored rows, ignored rows) by the MOTChallenge rules."""
    conf = gt[:, 6] if gt.shape[1] > 6 else np.ones(len(gt))
    has_class = gt.shape[1] == 9 and bool(np.all(gt[:, 7] >= 1))
    if has_class:
        cls = gt[:, 7].astype(int)
        ignored = (conf == 0) | np.isin(cls, DISTRACTOR_CLASSES)
        scored = ~ignored & (cls == PEDESTRIAN)
    else:
        ignored = conf == 0
        scored = ~ignored
    return gt[scored], gt[ignored]


def ignoring(gt: np.ndarray, ids: Sequence[int]) -> np.ndarray:
    """``gt`` with the rows of objects ``ids`` marked ignored (``conf`` 0): scored as the
    MOTChallenge rules score a distractor, neither a miss when no hypothesis covers it nor a false
    box when one does."""
    out = gt.copy()
    if len(out):
        out[np.isin(out[:, 1].astype(int), list(ids)), 6] = 0
    return out


def clip_boxes(boxes: np.ndarray, size: tuple[int, int] | None) -> np.ndarray:
    """Boxes (left, top, width, height) cut to an image of ``size`` (width, height), if known."""
    if size is None or len(boxes) == 0:
        return boxes
    x0 = np.clip(boxes[:, 0], 0, size[0])
    y0 = np.clip(boxes[:, 1], 0, size[1])
    x1 = np.clip(boxes[:, 0] + boxes[:, 2], 0, size[0])
    y1 = np.clip(boxes[:, 1] + boxes[:, 3], 0, size[1])
    return np.stack([x0, y0, x1 - x0, y1 - y0], axis=1)


def iou_pairs(similarity: np.ndarray, threshold: float) -> list[tuple[int, int]]:
    """Hungarian pairs on 1 - IoU among pairs with IoU >= threshold."""
    if similarity.size == 0:
        return []
    cost = np.where(similarity >= threshold, 1.0 - similarity, 1e6)
    rows, cols = linear_sum_assignment(cost)
    return [(r, c) for r, c in zip(rows, cols, strict=True) if similarity[r, c] >= threshold]


def _not_ignored(
    g_box: np.ndarray, ignored_box: np.ndarray, h_box: np.ndarray, threshold: float
) -> np.ndarray:
    """Which hypotheses to score in a frame: those on ignored objects go, unless they belong to
    a scored object (the scored and ignored boxes are paired with them together)."""
    taken = iou_pairs(iou(np.concatenate([g_box, ignored_box]), h_box), threshold)
    drop = {c for r, c in taken if r >= len(g_box)}
    return np.array([i not in drop for i in range(len(h_box))], bool)


def _clear_mot_matches(
    sim: np.ndarray,
    g_ids: np.ndarray,
    h_ids: np.ndarray,
    last_match: dict[int, int],
    threshold: float,
) -> tuple[list[tuple[int, int]], int]:
    """One frame's CLEAR-MOT matches (rows of ``sim``, columns) and identity switches: last
    frame's correspondences (``last_match``, ground-truth id -> hypothesis id) that still
    hold are kept, the rest are paired by the Hungarian method."""
    matched: list[tuple[int, int]] = []
    switches = 0
    h_index = {int(j): c for c, j in enumerate(h_ids)}
    for r, i in enumerate(g_ids):
        c = h_index.get(last_match.get(int(i), -1))
        if c is not None and sim[r, c] >= threshold:
            matched.append((r, c))
    free_r = [r for r in range(len(g_ids)) if r not in {m[0] for m in matched}]
    free_c = [c for c in range(len(h_ids)) if c not in {m[1] for m in matched}]
    for r, c in iou_pairs(sim[np.ix_(free_r, free_c)], threshold):
        r, c = free_r[r], free_c[c]
        i, j = int(g_ids[r]), int(h_ids[c])
        if i in last_match and last_match[i] != j:
            switches += 1
        matched.append((r, c))
    return matched, switches


class ClearMot:
    """CLEAR-MOT and IDF1 accumulated frame by frame from any similarity of ground-truth
    objects and hypotheses (IoU of image boxes here; the demo uses nearness on the ground):
    pairs match when their similarity is at least ``threshold``."""

    def __init__(self, threshold: float) -> None:
        self.threshold = threshold
        self._last_match: dict[int, int] = {}
        self._fp = self._fn = self._switches = self._matches = self._n_hyp = self._n_gt = 0
        self._overlap = 0.0
        self._frames = 0
        self._pairs: dict[tuple[int, int], int] = {}
        self._gt_count: dict[int, int] = {}
        self._hyp_count: dict[int, int] = {}

    def add(self, g_ids: np.ndarray, h_ids: np.ndarray, sim: np.ndarray) -> list[tuple[int, int]]:
        """Score one frame: ground-truth ids, hypothesis ids and their ``(len(g_ids),
        len(h_ids))`` similarity; the matched pairs (row, column)."""
        self._frames += 1
        self._n_gt += len(g_ids)
        self._n_hyp += len(h_ids)
        for i in g_ids:
            self._gt_count[int(i)] = self._gt_count.get(int(i), 0) + 1
        for j in h_ids:
            self._hyp_count[int(j)] = self._hyp_count.get(int(j), 0) + 1
        for r, c in zip(*np.nonzero(sim >= self.threshold), strict=True):
            key = (int(g_ids[r]), int(h_ids[c]))
            self._pairs[key] = self._pairs.get(key, 0) + 1
        matched, switched = _clear_mot_matches(sim, g_ids, h_ids, self._last_match, self.threshold)
        self._switches += switched
        for r, c in matched:
            self._last_match[int(g_ids[r])] = int(h_ids[c])
            self._overlap += float(sim[r, c])
        self._matches += len(matched)
        self._fn += len(g_ids) - len(matched)
        self._fp += len(h_ids) - len(matched)
        return matched

    def scores(self) -> TrackingScores:
        """The scores of the frames added so far (``motp``: the matched pairs' mean
        similarity)."""
        n_gt, n_hyp, matches = self._n_gt, self._n_hyp, self._matches
        idtp = _identity_matches(self._pairs, self._gt_count, self._hyp_count)
        return TrackingScores(
            mota=1.0 - (self._fn + self._fp + self._switches) / n_gt if n_gt else float("nan"),
            motp=self._overlap / matches if matches else float("nan"),
            idf1=2 * idtp / (n_gt + n_hyp) if n_gt + n_hyp else float("nan"),
            idp=idtp / n_hyp if n_hyp else float("nan"),
            idr=idtp / n_gt if n_gt else float("nan"),
            id_switches=self._switches,
            fp=self._fp,
            fn=self._fn,
            matches=matches,
            gt_boxes=n_gt,
            hypothesis_boxes=n_hyp,
            frames=self._frames,
            gt_ids=len(self._gt_count),
            hypothesis_ids=len(self._hyp_count),
        )


def evaluate_tracking(
    gt: np.ndarray,
    hypotheses: np.ndarray,
    threshold: float = 0.5,
    image_size: tuple[int, int] | None = None,
) -> TrackingScores:
    """Scores of MOT rows ``hypotheses`` against MOT rows ``gt``."""
    scored, ignored = split_gt(gt)
    frames = sorted(set(scored[:, 0].astype(int)) | set(hypotheses[:, 0].astype(int)))
    mot = ClearMot(threshold)
    for f in frames:
        g = scored[scored[:, 0] == f]
        h = hypotheses[hypotheses[:, 0] == f]
        g_box, h_box = clip_boxes(g[:, 2:6], image_size), h[:, 2:6]
        ign = ignored[ignored[:, 0] == f]
        if len(ign) and len(h):
            keep = _not_ignored(g_box, clip_boxes(ign[:, 2:6], image_size), h_box, threshold)
            h, h_box = h[keep], h_box[keep]
        sim = iou(g_box, h_box) if len(g) and len(h) else np.zeros((len(g), len(h)))
        mot.add(g[:, 1].astype(int), h[:, 1].astype(int), sim)
    return mot.scores()


def _identity_matches(
    pairs: dict[tuple[int, int], int], gt_count: dict[int, int], hyp_count: dict[int, int]
) -> int:
    """IDTP: frames matched under the best one-to-one pairing of whole trajectories."""
    if not pairs:
        return 0
    g_index = {i: k for k, i in enumerate(gt_count)}
    h_index = {j: k for k, j in enumerate(hyp_count)}
    together = np.zeros((len(g_index), len(h_index)))
    for (i, j), n in pairs.items():
        together[g_index[i], h_index[j]] = n
    rows, cols = linear_sum_assignment(-together)
    return int(together[rows, cols].sum())
