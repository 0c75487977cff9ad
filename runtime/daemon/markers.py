"""The daemon's marker search, on a thread of its own: the search of one frame at a time does not
hold up the world models of the frames meanwhile (at 640x480 about 9 ms of the whole image, 5 ms
following the markers found before, the grey image's decoding included)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

    from percept.drivers.camera.base import Frame
    from percept.kinematics.pose import CameraPose
    from percept.perception.landmarks.detection.detector import Marker

#: The search of one image seen from a camera pose (``BoxEstimator.search``).
Detect = Callable[["np.ndarray", "CameraPose"], "list[Marker]"]


class MarkerSearch:
    """The marker search of one frame at a time, on a thread of its own (:meth:`run`).

    :meth:`take` hands it a frame and its camera pose if it is idle; :meth:`finished` gives
    the markers of the frames searched since the last call, by frame ``seq``, in the order they
    were taken. The frame's full-size grey image is made on this thread (a camera that gives
    perception its grid decodes it only for the frames searched here, from its luma: no BGR
    image is made for the search).
    """

    def __init__(self, detect: Detect, stop: threading.Event) -> None:
        self._detect = detect
        self._stop = stop
        self._cond = threading.Condition()
        self._job: tuple[Frame, CameraPose] | None = None
        self._busy = False
        self._done: dict[int, list[Marker]] = {}

    def take(self, frame: Frame, camera_pose: CameraPose) -> bool:
        """Search ``frame`` unless a search is under way; whether it was taken."""
        with self._cond:
            if self._busy:
                return False
            self._job, self._busy = (frame, camera_pose), True
            self._cond.notify()
            return True

    def finished(self) -> dict[int, list[Marker]]:
        with self._cond:
            done, self._done = self._done, {}
            return done

    def run(self) -> None:
        while not self._stop.is_set():
            with self._cond:
                if self._job is None:
                    self._cond.wait(0.2)
                    continue
                frame, camera_pose = self._job
                self._job = None
            markers = self._detect(frame.gray, camera_pose)
            with self._cond:
                self._done[frame.seq] = markers
                self._busy = False
