"""The daemon's background before its first world model: loaded from ``--background``, or
calibrated on the camera's next frames, each with the joint angles at its time (its camera pose).

With gaze the head sweeps its working range meanwhile (:class:`~percept.runtime.daemon.gaze.
CalibrationSweep`, which also paces the frames taken); otherwise the devices pace them (a
simulated head's sweep). The frames are streamed into the calibration as they come: no list of
frames is held.
"""

from __future__ import annotations

import itertools
import logging
import math
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from percept.runtime.daemon.pipeline import FrameInputs, perception_frame

if TYPE_CHECKING:
    from percept.perception.segmentation.grid_frame import PerceptionFrame
    from percept.runtime.daemon.devices import Devices
    from percept.runtime.daemon.gaze import Gaze
    from percept.runtime.daemon.pipeline import Pipeline
    from percept.runtime.record.telemetry import Telemetry

log = logging.getLogger("percept.daemon")


class Pacer(Protocol):
    """Which frames the background calibration takes (``Devices``, ``CalibrationSweep``)."""

    def wanted(self, t: float, taken: int, needed: int) -> bool: ...


class Stopped(Exception):
    """Stopped while calibrating the background."""


@dataclass
class BackgroundStart:
    """Loads or calibrates one daemon's background; :attr:`state` is the status's
    ``background`` meanwhile, :attr:`without_joints` the frames passed over for want of a joint
    reading."""

    path: Path | None
    """``--background``: loaded when the file exists, else written after the calibration."""
    joint_delay: float
    """``[camera] joint_delay``: the joint angles are read at the frame's time plus this."""
    stop: threading.Event
    state: str = "not started"
    without_joints: int = 0
    last_taken: float = field(default=-math.inf, init=False)
    """Camera time of the last calibration frame taken."""

    @property
    def phase(self) -> str:
        """:attr:`state` without its details, its first word (``calibrating``, not
        ``calibrating 12/30``): not, loaded, calibrating or calibrated."""
        return self.state.partition(" ")[0]

    def prepare(
        self,
        pipeline: Pipeline,
        devices: Devices,
        telemetry: Telemetry | None,
        gaze: Gaze | None,
    ) -> bool:
        """Load the background model, or calibrate it on the next frames (progress logged),
        with ``gaze`` sweeping the head meanwhile; False when stopped first."""
        from percept.runtime.daemon.gaze import CalibrationSweep

        path = self.path
        if path is not None and path.exists():
            pipeline.load_background(path)
            self.state = f"loaded {path}"
            log.info("background loaded from %s", path)
            return True
        needed = pipeline.calibration_frames
        self.state = f"calibrating 0/{needed}"
        log.info("calibrating the background on %d frames: keep the scene empty", needed)
        if devices.sweep > 0:
            log.info("the simulated head sweeps for %.1f s meanwhile", devices.sweep)
        # With gaze the head sweeps the working range meanwhile (the simulated scene then holds
        # still at time 0); else the frames are paced by the devices (a simulated sweep).
        sweep = None if gaze is None else CalibrationSweep(gaze)
        pace: Pacer = devices if sweep is None else sweep
        if sweep is not None:
            sweep.start()
        try:
            with devices.calibration():
                # Two views of one stream: tee keeps only what one side has read ahead of the
                # other (a frame or two when the calibration takes an image, then its pose).
                frames = self._frames(devices, pace, needed)
                images, inputs = itertools.tee(frames)
                pipeline.calibrate((i for i, _ in images), self._progress, (f for _, f in inputs))
        except Stopped:
            return False
        finally:
            if sweep is not None:
                sweep.finish(self.stop)
        self.state = f"calibrated on {needed} frames"
        clock = devices.clock
        if devices.sweep > 0 and clock is not None and clock.at(self.last_taken) > devices.sweep:
            log.warning(
                "the last calibration frame shows scene time %.1f s, after the sweep over the "
                "empty floor (%.1f s): objects may be in the background model",
                clock.at(self.last_taken),
                devices.sweep,
            )
        if path is not None:
            pipeline.save_background(path)
            log.info("background saved to %s", path)
        if telemetry is not None:
            telemetry.attach_background(pipeline)
        return True

    def _frames(
        self, devices: Devices, pace: Pacer, needed: int
    ) -> Iterator[tuple[PerceptionFrame, FrameInputs]]:
        """The frames ``pace`` wants, each with its inputs (the joint angles at its time), as
        they come."""
        taken = 0
        while True:
            if self.stop.is_set():
                raise Stopped
            frame = devices.camera.wait(timeout=0.5)
            if frame is None:
                continue
            devices.start_sweep()
            if not pace.wanted(frame.t, taken, needed):
                continue
            sample = devices.joints.angles_at(frame.t + self.joint_delay)
            if sample is None:  # no joint reading yet: no camera pose
                self.without_joints += 1
                continue
            taken += 1
            self.last_taken = frame.t
            if taken == 1 and devices.sweep > 0 and devices.clock is not None:
                first = devices.clock.at(frame.t)
                log.info("the first calibration frame shows scene time %.1f s", first)
            yield perception_frame(frame), FrameInputs.of_frame(frame, sample)

    def _progress(self, done: int, total: int) -> None:
        self.state = f"calibrating {done}/{total}"
        if done % max(1, total // 5) == 0 or done == total:
            log.info("background calibration %d/%d frames", done, total)
