"""Foreground masks against CDnet ground truth: precision, recall, F1 and the other CDnet rates.

CDnet labels: 255 moving foreground (positive), 0 static background and 50 hard shadow
(negative), 85 outside the region of interest and 170 unknown motion (not scored). A mask pixel
is foreground when it is non-zero. Only pixels inside the spatial ROI (non-zero in ``ROI.bmp``)
of frames inside the temporal ROI (``temporalROI.txt``: first and last frame, 1-based) count,
and the counts are pooled over all frames before the rates are computed.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from percept.perception.evaluation.tracking import json_scores

POSITIVE = 255
NEGATIVE = (0, 50)
IGNORED = (85, 170)


@dataclass(frozen=True)
class ForegroundScores:
    """Pooled pixel counts and the CDnet rates computed from them."""

    tp: int
    fp: int
    fn: int
    tn: int
    frames: int

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else float("nan")

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else float("nan")

    @property
    def f1(self) -> float:
        p, r = self.precision, self.recall
        return 2 * p * r / (p + r) if p + r > 0 else float("nan")

    @property
    def specificity(self) -> float:
        return self.tn / (self.tn + self.fp) if self.tn + self.fp else float("nan")

    @property
    def pwc(self) -> float:
        """Percentage of wrong classifications."""
        total = self.tp + self.fp + self.fn + self.tn
        return 100.0 * (self.fp + self.fn) / total if total else float("nan")

    def as_dict(self) -> dict[str, object]:
        """Counts and rates for JSON; an undefined rate is None and ``undefined`` says why."""
        rates = {name: getattr(self, name) for name in _UNDEFINED}
        return json_scores(asdict(self) | rates, _UNDEFINED)


_UNDEFINED = {
    "precision": "no foreground in the masks",
    "recall": "no foreground in the ground truth",
    "f1": "precision and recall undefined or both 0",
    "specificity": "no background in the ground truth",
    "pwc": "no scored pixels",
}


def frame_counts(
    gt: np.ndarray, mask: np.ndarray, roi: np.ndarray | None = None
) -> tuple[int, int, int, int]:
    """(tp, fp, fn, tn) of one frame: CDnet label image ``gt``, any-nonzero ``mask``."""
    if gt.shape != mask.shape:
        raise ValueError(f"mask {mask.shape} and ground truth {gt.shape} differ in size")
    scored = ~np.isin(gt, IGNORED)
    if roi is not None:
        scored &= roi > 0
    positive = gt == POSITIVE
    negative = np.isin(gt, NEGATIVE)
    fg = mask > 0
    tp = int(np.count_nonzero(scored & positive & fg))
    fn = int(np.count_nonzero(scored & positive & ~fg))
    fp = int(np.count_nonzero(scored & negative & fg))
    tn = int(np.count_nonzero(scored & negative & ~fg))
    return tp, fp, fn, tn


def pooled(counts: Iterable[tuple[int, int, int, int]]) -> ForegroundScores:
    """Sum per-frame counts into scores."""
    total = np.zeros(4, np.int64)
    frames = 0
    for c in counts:
        total += c
        frames += 1
    tp, fp, fn, tn = (int(v) for v in total)
    return ForegroundScores(tp, fp, fn, tn, frames=frames)


def frame_number(path: Path) -> int | None:
    """The last number in a file's stem (``gt000470`` -> 470), or None."""
    digits = re.findall(r"\d+", path.stem)
    return int(digits[-1]) if digits else None


def read_temporal_roi(path: str | Path) -> tuple[int, int]:
    """(first, last) frame of CDnet's ``temporalROI.txt``."""
    first, last = (int(v) for v in Path(path).read_text(encoding="utf-8").split()[:2])
    return first, last
