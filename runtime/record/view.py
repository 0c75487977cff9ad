"""The live view: a Foxglove WebSocket server (foxglove-sdk) on the daemon's telemetry.

Connect Foxglove or Lichtblick to ``ws://127.0.0.1:PORT``. Besides everything the daemon records
(camera, joints, camera pose, world model, scene, boxes, status), the view serves images drawn only
while someone watches them: ``/live/anchors`` (the camera image with the anchors, Fig. 5.3h),
the perception's debug images (Fig. 5.2/5.3: foreground, motion, colour classification) under
``/live/<name>``, and ``/live/map``, the top-down map of Fig. 5.2e.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from percept.runtime.record.drawing import draw_anchors, draw_map

if TYPE_CHECKING:  # for types only: record does not import the daemon, foxglove loads on use
    import foxglove

    from percept.drivers.camera.base import Frame
    from percept.perception.pipeline import FrameResult
    from percept.runtime.daemon.pipeline import FrameOutput

log = logging.getLogger("percept.view")

MAX_RATE = 10.0  # drawn images per second at most: the view must not slow perception down


class LiveTelemetry(Protocol):
    """What the view serves from: the daemon's telemetry (its Foxglove context), and its
    live-only images, drawn only while someone subscribes."""

    context: foxglove.Context

    def wants_live(self, name: str) -> bool: ...

    def log_live_image(self, name: str, image: np.ndarray, wall: float) -> None: ...


class LiveView:
    """Serves the telemetry of one daemon over a Foxglove WebSocket on 127.0.0.1."""

    def __init__(
        self, telemetry: LiveTelemetry, robot: str, port: int, host: str = "127.0.0.1"
    ) -> None:
        import foxglove

        self.telemetry = telemetry
        self.server = foxglove.start_server(
            name=f"percept {robot}", host=host, port=port, context=telemetry.context
        )
        self.port = self.server.port
        self._next = 0.0
        log.info("live view on ws://%s:%d (Foxglove: open connection)", host, self.port)

    def update(self, frame: Frame, out: FrameOutput) -> None:
        """Draw and send the live images of a processed frame, at most :data:`MAX_RATE` a second."""
        now = time.monotonic()
        if now < self._next:
            return
        self._next = now + 1.0 / MAX_RATE
        tel, wall = self.telemetry, frame.wall
        if out.world is not None:
            if tel.wants_live("anchors"):
                tel.log_live_image("anchors", draw_anchors(frame.image, out.world), wall)
            if tel.wants_live("map"):
                tel.log_live_image("map", draw_map(out.world), wall)
        for name, image in debug_images(out.result, tel.wants_live):
            tel.log_live_image(name, image, wall)

    def close(self) -> None:
        self.server.stop()


def debug_images(
    result: FrameResult | None, wanted: Callable[[str], bool]
) -> list[tuple[str, np.ndarray]]:
    """The perception's Fig. 5.2/5.3 debug images (foreground, colour classes) that someone
    watches; none for a skipped frame."""
    from percept.perception import debug

    if result is None or result.masks is None:
        return []
    drawings = {"foreground": debug.foreground_image, "classes": debug.classes_image}
    return [(name, draw(result)) for name, draw in drawings.items() if wanted(name)]
