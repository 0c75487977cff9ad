"""False anchors: anchors in view that match no true object.

In each frame, anchors (hypothesis boxes) and true objects are paired one to one at IoU 0.5 or
more (the Hungarian pairing of :func:`~percept.perception.evaluation.tracking.iou_pairs`); an
anchor left unpaired is false in that frame. An anchor's false time is the number of frames it
is false in, over the frame rate; a *persistent* false anchor is one false for longer than a
limit in all (10 s in the robustness benchmark), whether or not it also matched sometimes.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import TypeVar

import numpy as np

from percept.perception.evaluation.tracking import iou, iou_pairs, split_gt


def false_seconds(gt: np.ndarray, hypotheses: np.ndarray, fps: float) -> dict[int, float]:
    """Per anchor (hypothesis id) that was ever false, the seconds it was false; MOT rows."""
    scored, _ = split_gt(gt)
    frames: dict[int, int] = {}
    for f in np.unique(hypotheses[:, 0].astype(int)):
        h = hypotheses[hypotheses[:, 0] == f]
        g = scored[scored[:, 0] == f]
        paired = {c for _, c in iou_pairs(iou(g[:, 2:6], h[:, 2:6]), 0.5)} if len(g) else set()
        for c, j in enumerate(h[:, 1].astype(int)):
            if c not in paired:
                frames[int(j)] = frames.get(int(j), 0) + 1
    return {j: n / fps for j, n in frames.items()}


Anchor = TypeVar("Anchor", bound=Hashable)


def persistent(seconds: Mapping[Anchor, float], limit: float) -> int:
    """How many anchors were false for longer than ``limit`` seconds (any anchor ids: the MOT
    rows' numbers here, the world model's ids in the demo's scorecard)."""
    return sum(s > limit for s in seconds.values())
