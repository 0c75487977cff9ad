"""A frame given to perception at the size it works on: its grid, not the full image.

Perception looks at every ``step``-th pixel of every ``step``-th row. A camera that can deliver
that grid directly (a JPEG decoded at 1/step scale, a raw YUYV camera) saves decoding and
converting the pixels perception never looks at. Such a grid pixel is the average of its
``step`` x ``step`` block, not the one pixel a full frame's grid picks: less noise, softer
edges. So a background calibrated on grid frames takes only grid frames afterwards, and one
calibrated on full frames only full frames (:class:`~percept.perception.pipeline.Perception`
checks).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, TypeAlias

import numpy as np

from percept.perception.colour import to_ycrcb
from percept.perception.segmentation.labelling.regions import subsample


@dataclass(frozen=True)
class GridFrame:
    """The YCrCb image (uint8, ``ceil(H / step)`` x ``ceil(W / step)`` x 3) on perception's grid
    of every ``step``-th pixel of a frame."""

    ycc: np.ndarray
    step: int

    @classmethod
    def of(cls, image: np.ndarray, step: int, colour: Literal["bgr", "ycrcb"] = "bgr") -> GridFrame:
        """The grid frame of an image on the grid, BGR (converted as every frame is) or
        YCrCb."""
        return cls(to_ycrcb(image) if colour == "bgr" else image, step)


PerceptionFrame: TypeAlias = np.ndarray | GridFrame
"""What perception takes: a full-size BGR image, or a :class:`GridFrame`."""


def as_ycrcb(frame: PerceptionFrame) -> np.ndarray:
    """The YCrCb image of a frame at the size it came: a full frame's converted, a grid frame's
    own."""
    return frame.ycc if isinstance(frame, GridFrame) else to_ycrcb(frame)


def grid_ycrcb(frame: PerceptionFrame, step: int) -> np.ndarray:
    """The YCrCb image of a frame on the grid of every ``step``-th pixel (a full frame's picked
    pixels, a grid frame as it is)."""
    return frame.ycc if isinstance(frame, GridFrame) else to_ycrcb(subsample(frame, step))
