"""The ``perception`` thread: from each new frame to its world model on the network.

It takes the newest frame, the joint angles at its time and the peer messages that arrived
since the last frame, runs the :class:`~percept.runtime.daemon.pipeline.Pipeline`, hands every
``[landmarks] every``-th frame to the marker search (:mod:`percept.runtime.daemon.markers`,
whose result it applies at the next frame), and sends, records and shows the world model
(:class:`Outputs`). Before the first frame it prepares the background
(:mod:`percept.runtime.daemon.calibration`), which may take the head on its calibration sweep.

What it counts (frames, frames with old or no joint readings, the background's unknown share,
the frame rate) is read by the status while it runs, each value assigned whole.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from percept.runtime.daemon.markers import MarkerSearch
from percept.runtime.daemon.pipeline import FrameInputs, Pipeline, perception_frame
from percept.runtime.daemon.status import health

if TYPE_CHECKING:
    from percept.drivers.camera.base import Frame
    from percept.runtime.daemon.calibration import BackgroundStart
    from percept.runtime.daemon.devices import Devices
    from percept.runtime.daemon.gaze import Gaze
    from percept.runtime.daemon.pipeline import FrameOutput, PeerMessage
    from percept.runtime.daemon.publishing import Outbox
    from percept.runtime.net.mailbox import DropOldest
    from percept.runtime.net.messages import World
    from percept.runtime.record.telemetry import Telemetry
    from percept.runtime.record.view import LiveView
    from percept.runtime.ros2.publisher import Ros2Publisher
    from percept.runtime.settings.experiment import Experiment
    from percept.runtime.settings.profile import PlatformProfile


@dataclass(frozen=True)
class Outputs:
    """Where a frame's world model goes: the network, and the recording, the live view and ROS 2
    when the run has them."""

    outbox: Outbox
    telemetry: Telemetry | None = None
    view: LiveView | None = None
    ros2: Ros2Publisher | None = None


class PerceptionThread:
    """The perception thread's loop (:meth:`run`) and what it counts for the status."""

    def __init__(
        self,
        robot: str,
        profile: PlatformProfile,
        experiment: Experiment,
        background: BackgroundStart,
        inbox: DropOldest[tuple[float, PeerMessage]],
        stop: threading.Event,
    ) -> None:
        self.robot = robot
        self.profile = profile
        self.experiment = experiment
        self.background = background
        self.inbox = inbox
        self._stop = stop
        self.pipeline: Pipeline | None = None
        """Made when the thread begins (it knows the camera's resolution then)."""
        self.world: World | None = None
        """The last world model sent (None before the first)."""
        self.ready = False
        """The background is prepared and frames are processed."""
        self.frames = 0
        """Frames made into world models."""
        self.old_joint_frames = 0
        """Frames whose joint reading was older than the pipeline accepts as fresh."""
        self.frames_without_joints = 0
        """Frames passed over after the calibration for want of any joint reading."""
        self.unknown: float | None = None
        """The share of the last frame's view that the background has not seen yet."""
        self.progress = (0, -math.inf)
        """Frames finished, and when the last of them was taken (monotonic): for the looks."""
        self.last_frame = time.monotonic()
        """When the last frame came (monotonic)."""
        self.rate = health.Rate()

    @property
    def without_joints(self) -> int:
        """Frames passed over for want of a joint reading, in the calibration and after."""
        return self.frames_without_joints + self.background.without_joints

    def run(
        self,
        devices: Devices,
        outputs: Outputs,
        gaze: Gaze | None,
        spawn: Callable[[str, Callable[[], None]], None],
        on_ready: Callable[[], None],
    ) -> None:
        """Prepare the background, start the marker search's thread with ``spawn``, call
        ``on_ready`` and process frames until the stop."""
        width, height = devices.resolution
        pipeline = self.pipeline = Pipeline(
            self.robot,
            self.profile,
            self.experiment,
            width,
            height,
            joint_max_age=self.experiment.daemon.joint_max_age,
        )
        if not self.background.prepare(pipeline, devices, outputs.telemetry, gaze):
            return
        search = MarkerSearch(pipeline.boxes.search, self._stop)
        spawn("markers", search.run)
        every = self.experiment.landmarks.every
        since_search = every  # the first frame is searched
        self.ready = True
        on_ready()
        self.last_frame = time.monotonic()
        joint_delay = self.profile.camera.joint_delay
        while not self._stop.is_set():
            frame = devices.camera.wait(timeout=0.2)
            if frame is None:
                continue
            began = time.monotonic()
            self.last_frame = began
            sample = devices.joints.angles_at(frame.t + joint_delay)
            if sample is None:  # no joint reading yet: no camera pose, nothing to publish
                self.frames_without_joints += 1
                continue
            found = search.finished()
            peer_messages = tuple(self.inbox.drain())
            inputs = FrameInputs.of_frame(frame, sample, peer_messages, tuple(found))
            taken = perception_frame(frame, pipeline.perception.grid_frames)
            out = pipeline.step(taken, inputs, found)
            since_search += 1
            if since_search >= every and out.pose is not None and search.take(frame, out.pose.pose):
                since_search = 0
            self.frames += 1
            if out.result is not None:
                self.unknown = round(out.result.unknown_fraction, 4)
            if out.pose is None or not out.pose.fresh:
                self.old_joint_frames += 1
            self._output(frame, inputs, out, began, outputs)
            # For the looks, once the frame's world model is out; one assignment, read whole.
            self.progress = (self.frames, frame.t)
            self.rate.add(time.monotonic(), time.monotonic() - began)

    def _output(
        self, frame: Frame, inputs: FrameInputs, out: FrameOutput, began: float, outputs: Outputs
    ) -> None:
        """A frame's world model sent, the frame recorded and shown in the live view."""
        payload = None
        if out.world is not None:
            payload = outputs.outbox.world(out.world, began)
            if payload is not None:
                self.world = out.world
        telemetry = outputs.telemetry
        if telemetry is not None:
            # The full image only where it is recorded (and the live view's drawings ask).
            telemetry.log_frame(inputs.record(), lambda: frame.image)
            if out.pose is not None:
                telemetry.log_pose(frame.wall, out.pose.pose.R, out.pose.pose.t)
            if out.world is not None and payload is not None:  # recorded: what goes on Zenoh
                telemetry.log_world(out.world, frame.wall, payload)
        if out.world is not None and payload is not None and outputs.ros2 is not None:
            outputs.ros2.offer(out.world, inputs.joints, lambda: frame.image)
        if outputs.view is not None:
            outputs.view.update(frame, out)
