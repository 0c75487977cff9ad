"""One frame's way through the daemon (SPEC §2), as a deterministic function of its inputs.

:class:`Pipeline` turns a frame's image and the joint angles at its time into a world model
(:class:`~percept.runtime.net.messages.World`): camera pose by forward kinematics, perception
(background, foreground, colour split, motion, anchors), the seven features per anchor and their
scaled values, box poses from marker landmarks, and the peers' poses from the box messages
received before this frame. Nothing here reads a clock or a device: the daemon and ``percept
replay`` feed it the same :class:`FrameInputs` and get the same world models.

The marker search (6-10 ms at 640x480 with the default detector, 25-55 ms with cv2.aruco's and
AprilTag's corners) does not hold up the frames: the daemon runs it on a thread of its own, on
about every ``[landmarks] every``-th frame, and hands its results to :meth:`Pipeline.step` at a
later frame, whose inputs name the searched frames applied (``marker_frames``); a replay
searches those same frames again, with the same camera poses and in the same order
(``boxes.search`` follows known markers between full searches), and applies them at the same
point.
"""

from __future__ import annotations

import logging
import math
from collections import OrderedDict
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from percept.runtime.daemon.status.health import finite
from percept.runtime.net.codec import JSON, read, write
from percept.runtime.net.messages import Boxes, Camera, PeerPose, World, WorldAgent, WorldObject

if TYPE_CHECKING:
    from percept.drivers.camera.base import Frame
    from percept.drivers.joints import JointSample
    from percept.kinematics.frame_pose import FramePose
    from percept.kinematics.pose import CameraPose
    from percept.perception.features.experience import SensoryExperience
    from percept.perception.landmarks.boxes import BoxEstimator
    from percept.perception.landmarks.detection.detector import Marker
    from percept.perception.landmarks.records import BoxPose
    from percept.perception.pipeline import FrameResult
    from percept.perception.segmentation.grid_frame import PerceptionFrame
    from percept.perception.tracking.anchors import Anchor
    from percept.runtime.net.settings import PeerSettings
    from percept.runtime.settings.experiment import Experiment
    from percept.runtime.settings.profile import PlatformProfile

log = logging.getLogger("percept.pipeline")

RECENT_FRAMES = 64  # camera poses kept for marker searches that finish frames later


@dataclass(frozen=True)
class Alive:
    """A liveliness change among the peer messages: process ``robot``'s token appeared or went
    (recorded as ``{"robot": ..., "alive": ...}``)."""

    robot: str
    alive: bool


PeerMessage = Boxes | Alive


@dataclass(frozen=True)
class FrameInputs:
    """Everything a frame's world model depends on besides the image.

    ``joints`` are the angles at the frame's time ``t`` (None: no joint reading yet);
    ``peer_messages`` are the peers' ``percept.boxes/1`` messages and liveliness changes
    (:class:`Alive`) that arrived since the last frame, each as ``(monotonic arrival time,
    message)``. ``marker_frames`` are the earlier frames (``seq``) whose marker search finished
    since the last frame, applied before this one.
    """

    seq: int
    t: float
    wall: float
    joints: Mapping[str, float] | None
    joint_age: float | None = None
    stale_joints: tuple[str, ...] = ()
    peer_messages: tuple[tuple[float, PeerMessage], ...] = ()
    marker_frames: tuple[int, ...] = ()

    def record(self) -> dict[str, JSON]:
        """As the JSON of ``/percept/frame`` in a recording."""
        return {
            "seq": self.seq,
            "t": self.t,
            "wall": self.wall,
            "joints": None if self.joints is None else dict(self.joints),
            "joint_age": None
            if self.joint_age is None or math.isinf(self.joint_age)
            else self.joint_age,
            "stale_joints": list(self.stale_joints),
            "peer_messages": [[t, write(m, "peer message")] for t, m in self.peer_messages],
            "marker_frames": list(self.marker_frames),
        }

    @classmethod
    def from_record(cls, data: Mapping[str, Any]) -> FrameInputs:
        """The inverse of :meth:`record` (``data`` as ``json.loads`` gives it: the conversions
        here are its checks)."""
        return cls(
            seq=int(data["seq"]),
            t=float(data["t"]),
            wall=float(data["wall"]),
            joints=data.get("joints"),
            joint_age=data.get("joint_age"),
            stale_joints=tuple(data.get("stale_joints") or ()),
            peer_messages=tuple(
                (float(t), _peer_message(m)) for t, m in data.get("peer_messages") or ()
            ),
            marker_frames=tuple(int(seq) for seq in data.get("marker_frames") or ()),
        )

    @classmethod
    def of_frame(
        cls,
        frame: Frame,
        sample: JointSample,
        peer_messages: tuple[tuple[float, PeerMessage], ...] = (),
        marker_frames: tuple[int, ...] = (),
    ) -> FrameInputs:
        """The inputs of a camera's ``frame``: the joint angles at its time, the peer messages
        that arrived since the last frame and the frames whose marker search finished
        meanwhile."""
        return cls(
            seq=frame.seq,
            t=frame.t,
            wall=frame.wall,
            joints=sample.angles,
            joint_age=finite(sample.age),
            stale_joints=tuple(sorted(sample.stale)),
            peer_messages=peer_messages,
            marker_frames=marker_frames,
        )


def perception_frame(frame: Frame, grid: bool = True) -> PerceptionFrame:
    """What perception takes of a camera frame: its grid image when the camera gave one (the
    full image is then made only for what needs it), else the full BGR image. ``grid`` False:
    the full image whatever the camera gave (a background saved from full-size frames, as
    before the cameras gave grid frames, keeps working; it only misses the saving)."""
    from percept.perception.segmentation.grid_frame import GridFrame

    if frame.grid is None or not grid:
        return frame.image
    return GridFrame.of(frame.grid, frame.step, frame.grid_colour)


def _peer_message(data: Mapping[str, JSON]) -> PeerMessage:
    if "alive" in data:
        return read(Alive, data, "peer alive")
    return Boxes.from_json(data, "peer boxes")


@dataclass
class FrameOutput:
    """A frame's world model (None without joint readings: no camera pose, nothing to send),
    and what the live view draws from (not sent anywhere)."""

    world: World | None
    pose: FramePose | None = None
    result: FrameResult | None = None


class Pipeline:
    """From frames and joint angles to world models, for one robot.

    Build it from the robot's profile and the experiment, calibrate or load the background, then
    call :meth:`step` once per frame, in order. Single-threaded except :meth:`boxes`, which the
    5 Hz publisher may call from its own thread.
    """

    def __init__(
        self,
        robot: str,
        profile: PlatformProfile,
        experiment: Experiment,
        width: int,
        height: int,
        joint_max_age: float,
    ) -> None:
        from percept.kinematics.camera import CameraModel
        from percept.kinematics.frame_pose import FramePoses
        from percept.kinematics.tree import KinematicTree
        from percept.perception.features.agents import AgentJudge, ObjectsAndAgents
        from percept.perception.features.experience import SensoryMemory
        from percept.perception.features.scaling import FeatureScaling
        from percept.perception.landmarks.boxes import BoxEstimator
        from percept.perception.pipeline import Perception

        self.robot = robot
        self.tree = KinematicTree.from_settings(profile.kinematics)
        self._poses = FramePoses(self.tree, joint_max_age)
        self.camera = CameraModel.from_lens(profile.camera.lens, width, height)
        self.scaling = FeatureScaling.from_settings(experiment.scaling)
        self.features = SensoryMemory(self.camera, experiment.features)
        self.perception = Perception(experiment.perception, width, height, self.camera)
        judge = AgentJudge(experiment.features.max_object_height, width, height)
        self.sorting = ObjectsAndAgents(judge, self.features)
        self.boxes = BoxEstimator(experiment.landmarks, self.camera)
        self.peers = _Peers(robot, self.boxes, experiment.peers)
        self._recent: OrderedDict[int, tuple[CameraPose, float]] = OrderedDict()  # seq: (pose, t)

    # -- background -------------------------------------------------------------------------------

    @property
    def calibration_frames(self) -> int:
        """How many object-free frames the background calibration takes."""
        return self.perception.params.background.calibration_frames

    def calibrate(
        self,
        images: Iterable[PerceptionFrame],
        progress: Callable[[int, int], None] | None = None,
        inputs: Iterable[FrameInputs] | None = None,
    ) -> None:
        """Background statistics from object-free images (BGR, or grid frames: then the frames
        after them must be grid frames too); ``progress(done, total)``. ``inputs``
        are the images' frame inputs in the same order: their joint angles give each image's
        camera pose, by forward kinematics as in :meth:`step` (None: a still camera)."""
        poses = None if inputs is None else (self._calibration_pose(i) for i in inputs)
        self.perception.calibrate(images, progress, poses)

    def _calibration_pose(self, inputs: FrameInputs) -> CameraPose:
        frame_pose = self._frame_pose(inputs)
        if frame_pose is None:
            raise ValueError(f"calibration frame {inputs.seq} has no joint angles")
        return frame_pose.pose

    def save_background(self, path: str | Path) -> None:
        self.perception.save_background(path)

    def load_background(self, path: str | Path) -> None:
        self.perception.load_background(path)

    # -- per frame --------------------------------------------------------------------------------

    def step(
        self,
        image: PerceptionFrame,
        inputs: FrameInputs,
        markers: Mapping[int, list[Marker]] | None = None,
    ) -> FrameOutput:
        """The world model of one frame (a BGR image, or a grid frame); ``markers`` holds the
        markers found in each frame of ``inputs.marker_frames``."""
        from percept.perception.tracking.known import marker_boxes

        for arrived, message in inputs.peer_messages:
            # its wall-clock arrival: the frames' clock and the messages' are one
            self.peers.receive(message, arrived, arrived + inputs.wall - inputs.t)
        frame_pose = self._frame_pose(inputs)
        result = self.perception.process(
            image,
            inputs.t,
            None if frame_pose is None else frame_pose.pose,
            frame_pose is None or frame_pose.fresh,
            marker_boxes(self.boxes, inputs.t),  # known objects, never anchors
        )
        pose = None if frame_pose is None else frame_pose.pose
        wall = inputs.wall - inputs.t  # the wall clock when the frames' clock read 0
        objects: list[WorldObject] = []
        agents: list[WorldAgent] = []
        # Without a camera pose there are no experiences and no world model: its objects are
        # not made.
        for one in self.sorting.sort(result, pose, self.perception.tracker.turn):
            if one.experience is None:
                continue
            if one.reason is None:
                objects.append(self._object(one.anchor, one.experience, wall))
            else:  # a person, not an object: never a topic of the games
                agents.append(_agent(one.anchor, one.experience, one.reason))
        self._markers(inputs, frame_pose, markers or {})
        boxes = self.boxes.boxes(inputs.t)
        peers = self.peers.poses(inputs.t, boxes)
        if frame_pose is None:
            return FrameOutput(world=None, pose=None, result=result)
        world = World(
            robot=self.robot,
            stamp=inputs.wall,
            t=inputs.t,
            frame=inputs.seq,
            camera=_camera(frame_pose.pose),
            pose_fresh=frame_pose.fresh,
            objects=tuple(objects),
            boxes=tuple(boxes),
            peers=peers,
            agents=tuple(agents),
        )
        return FrameOutput(world=world, pose=frame_pose, result=result)

    def _frame_pose(self, inputs: FrameInputs) -> FramePose | None:
        """The camera pose by forward kinematics at the frame's joint angles (None without)."""
        from percept.drivers.joints import JointSample

        if not inputs.joints:
            return None
        sample = JointSample(
            angles=dict(inputs.joints),
            t=inputs.t,
            age=inputs.joint_age or 0.0,
            stale=frozenset(inputs.stale_joints),
        )
        return self._poses(sample)

    def _object(self, anchor: Anchor, exp: SensoryExperience, wall: float) -> WorldObject:
        """One anchor in the world model: its seven features ``exp`` and their scaled values;
        ``wall`` is the wall-clock time at which the frames' clock read 0."""
        left, top, width, height = (float(v) for v in anchor.bbox)
        return WorldObject(
            id=anchor.id,
            bbox=(left, top, width, height),
            features=exp.features(),
            scaled=self.scaling.scale(exp),
            on_ground=exp.on_ground,
            age=float(anchor.age),
            in_motion=bool(anchor.in_motion),
            visible=anchor.visible,
            last_seen=max(0.0, wall + anchor.last_seen),
        )

    def _markers(
        self, inputs: FrameInputs, frame_pose: FramePose | None, markers: Mapping[int, list[Marker]]
    ) -> None:
        """Box poses from the marker searches that finished before this frame; this frame's
        camera pose kept for its own search."""
        for seq in inputs.marker_frames:
            seen = self._recent.get(seq)
            if seen is None:  # a frame without a camera pose, or too long ago
                log.debug("markers of frame %d dropped: no camera pose kept for it", seq)
                continue
            self.boxes.observe(markers[seq], *seen)
        if frame_pose is not None:
            self._recent[inputs.seq] = (frame_pose.pose, inputs.t)
            while len(self._recent) > RECENT_FRAMES:
                self._recent.popitem(last=False)


def _agent(anchor: Anchor, exp: SensoryExperience, reason: str) -> WorldAgent:
    """An anchor that is an agent, as the world model reports it."""
    left, top, width, height = (float(v) for v in anchor.bbox)
    return WorldAgent(
        id=anchor.id,
        bbox=(left, top, width, height),
        reason=reason,
        x=exp.x,
        y=exp.y,
        height=exp.height,
        in_motion=bool(anchor.in_motion),
        visible=anchor.visible,
    )


def _camera(pose: CameraPose) -> Camera:
    """The camera pose as the world model's camera (as in ``CameraPose.as_dict()``)."""
    fields = pose.as_dict()
    return Camera(R=fields["R"], t=fields["t"], frame=fields["frame"])


class _Peers:
    """The peers' poses from their box messages (:class:`percept.runtime.net.peers.PeerTracker`), on
    the frames' clock: a message counts from its arrival time, a pose is asked at a frame's time, so
    a replay gives the same poses."""

    def __init__(self, robot: str, boxes: BoxEstimator, settings: PeerSettings) -> None:
        from percept.runtime.net.peers import PeerTracker

        self.now = -math.inf
        self._boxes = boxes
        self.tracker = PeerTracker(robot, self._my_boxes, settings, clock=lambda: self.now)

    def _my_boxes(self) -> list[BoxPose]:
        return self._boxes.boxes(self.now)

    def receive(self, message: PeerMessage, arrived: float, wall: float) -> None:
        """A peer message that arrived at ``arrived`` on the frames' clock, ``wall`` on the
        wall clock."""
        self.now = arrived
        if isinstance(message, Alive):
            self.tracker.on_alive(message.robot, message.alive)
        else:
            self.tracker.on_boxes(message, wall)

    def poses(self, t: float, mine: list[BoxPose]) -> dict[str, PeerPose]:
        """The peers' poses at frame time ``t``, given my boxes at ``t``."""
        self.now = t
        return self.tracker.poses(mine)
