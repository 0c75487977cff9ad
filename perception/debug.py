"""Debug images like the chapter's Fig. 5.2 and 5.3, from one frame's :class:`FrameResult`.

- :func:`foreground_image`: foreground white, background black, region boxes in green and the
  boxes of moving models in blue (Fig. 5.2b, 5.3d-e);
- :func:`classes_image`: each foreground pixel in the mean colour of the model it was given to,
  white where no model explains it (Fig. 5.3f);
- :func:`anchors_image`: the camera image with each anchor's box in its model's mean colour and
  its id (Fig. 5.3h);
- :func:`panel`: the three and the camera image in a 2x2 grid.
"""

from __future__ import annotations

import cv2
import numpy as np

from percept.perception.colour import histogram_means, ycrcb_bgr
from percept.perception.pipeline import FrameResult
from percept.perception.tracking.anchors import Anchor

MOTION = (255, 80, 0)
REGION = (0, 200, 0)


def _bgr(histograms: np.ndarray) -> tuple[int, int, int]:
    """Mean colour of (3, m) YCrCb histograms as a BGR triple."""
    return ycrcb_bgr(histogram_means(histograms))


def foreground_image(result: FrameResult) -> np.ndarray:
    """Foreground mask with region boxes (green) and moving anchors' boxes (blue)."""
    if result.masks is None:
        raise ValueError("the frame was skipped: no masks")
    image = cv2.cvtColor(result.masks.foreground, cv2.COLOR_GRAY2BGR)
    for left, top, w, h in result.masks.regions.boxes.tolist():
        cv2.rectangle(image, (left, top), (left + w - 1, top + h - 1), REGION, 1)
    for a in result.anchors:
        if a.in_motion:
            _box(image, a, MOTION)
    return image


def classes_image(result: FrameResult, anchors_before: list[Anchor] | None = None) -> np.ndarray:
    """Foreground pixels in the colour of their model (white: no model), black background.

    The models are those that took part in the split (``masks.class_ids``); their colours come
    from ``anchors_before`` when given, else from the anchors after the frame.
    """
    if result.masks is None:
        raise ValueError("the frame was skipped: no masks")
    known = {a.id: a for a in (anchors_before or result.anchors)}
    palette = np.zeros((len(result.masks.class_ids) + 2, 3), np.uint8)
    palette[1] = (255, 255, 255)
    for j, anchor_id in enumerate(result.masks.class_ids):
        if anchor_id in known:
            palette[j + 2] = _bgr(known[anchor_id].histograms)
    return palette[result.masks.classes + 1]


def anchors_image(frame_bgr: np.ndarray, anchors: list[Anchor]) -> np.ndarray:
    """The frame with every anchor's box and id; anchors not seen in this frame in grey."""
    image = frame_bgr.copy()
    for a in anchors:
        colour = _bgr(a.histograms) if a.visible else (128, 128, 128)
        _box(image, a, colour)
        left, top = int(a.bbox[0]), int(a.bbox[1])
        scale = max(0.3, image.shape[1] / 1200)
        cv2.putText(
            image, a.id, (left, max(top - 3, 8)), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 1
        )
    return image


def panel(frame_bgr: np.ndarray, result: FrameResult) -> np.ndarray:
    """Camera image, foreground, classification and anchors in a 2x2 grid."""
    top = np.hstack([frame_bgr, foreground_image(result)])
    bottom = np.hstack([classes_image(result), anchors_image(frame_bgr, result.anchors)])
    return np.vstack([top, bottom])


def _box(image: np.ndarray, anchor: Anchor, colour: tuple[int, int, int]) -> None:
    left, top, w, h = (round(v) for v in anchor.bbox)
    cv2.rectangle(image, (left, top), (left + w - 1, top + h - 1), colour, 1)
