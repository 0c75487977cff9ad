"""What tracking through head motion is measured by, beside MOTA and IDF1 (:mod:`.tracking`):
the anchors created per true object, the re-identification of objects that come back into view,
and the error of the ground positions percept gives, relative to the object's distance.

Track tables are MOTChallenge rows as :func:`~.tracking.read_mot` gives them. An anchor and a
ground-truth object match in a frame when their boxes overlap by IoU >= ``threshold``, paired
one-to-one by the Hungarian method (as in :func:`~.tracking.evaluate_tracking`).

**Re-identification.** An object *leaves the view* when it is missing from the ground truth for
at least ``min_gap`` frames (out of view, or hidden behind a nearer object; shorter gaps are
flicker at the image border, not a return) and *returns* when it is listed again. A return
counts when some anchor matched the object before it left; it is *re-identified* when the first
anchor that matches it within ``grace`` frames of its return is the last one that matched it
before it left. A return that no anchor matches within ``grace`` frames is not re-identified.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from percept.perception.evaluation.tracking import iou, iou_pairs, split_gt


def anchors_per_object(anchors_created: int, gt: np.ndarray) -> float:
    """Anchors created per object of the ground truth (NaN without objects)."""
    objects = len(set(split_gt(gt)[0][:, 1].astype(int)))
    return anchors_created / objects if objects else float("nan")


def frame_matches(
    gt: np.ndarray, hypotheses: np.ndarray, threshold: float = 0.5
) -> dict[int, dict[int, int]]:
    """Per frame, the anchor (hypothesis id) each matched ground-truth object (id) has."""
    scored, _ = split_gt(gt)
    out: dict[int, dict[int, int]] = {}
    for f in sorted(set(scored[:, 0].astype(int))):
        g = scored[scored[:, 0] == f]
        h = hypotheses[hypotheses[:, 0] == f]
        if not len(h):
            continue
        pairs = iou_pairs(iou(g[:, 2:6], h[:, 2:6]), threshold)
        out[f] = {int(g[r, 1]): int(h[c, 1]) for r, c in pairs}
    return out


@dataclass(frozen=True)
class Reidentification:
    """Returns into view and how many got their anchor back (see the module docstring)."""

    returns: int
    same: int

    @property
    def fraction(self) -> float:
        """The re-identified share of the returns (NaN without returns)."""
        return self.same / self.returns if self.returns else float("nan")


def reidentification(
    gt: np.ndarray,
    hypotheses: np.ndarray,
    min_gap: int = 15,
    grace: int = 30,
    threshold: float = 0.5,
) -> Reidentification:
    """How many objects that left the view for ``min_gap`` frames or more came back with the
    anchor they had before (see the module docstring)."""
    scored, _ = split_gt(gt)
    matches = frame_matches(gt, hypotheses, threshold)
    seen: defaultdict[int, list[int]] = defaultdict(list)
    for f, i in scored[:, :2].astype(int):
        seen[int(i)].append(int(f))
    returns = same = 0
    for obj, frames in seen.items():
        frames = sorted(set(frames))
        for left, back in itertools.pairwise(frames):
            if back - left <= min_gap:
                continue
            before = [matches[f][obj] for f in frames if f <= left and obj in matches.get(f, {})]
            if not before:
                continue
            after = [
                matches[f][obj] for f in range(back, back + grace + 1) if obj in matches.get(f, {})
            ]
            returns += 1
            same += bool(after) and after[0] == before[-1]
    return Reidentification(returns=returns, same=same)


def relative_ground_errors(
    estimated: np.ndarray, truth: np.ndarray, viewpoint: np.ndarray
) -> np.ndarray:
    """Each ground position's error as a fraction of the object's distance: ``|estimated -
    truth| / |truth - viewpoint|`` per row of (N, 2) ground (x, y) arrays, ``viewpoint`` the
    camera's position on the ground (below it)."""
    estimated, truth, viewpoint = (
        np.asarray(a, float).reshape(-1, 2) for a in (estimated, truth, viewpoint)
    )
    distance = np.linalg.norm(truth - viewpoint, axis=1)
    return np.linalg.norm(estimated - truth, axis=1) / np.where(distance > 0, distance, np.nan)
