"""``percept track``: run the perception core over a recorded sequence, write MOTChallenge tracks.

The background is learned from the sequence's first N frames (robust statistics, so people or
objects passing then are tolerated) or loaded with ``--background``. N is
``--calibration-frames``, else what the folder says (``calibrationFrames`` in the ``seqinfo.ini``
of ``percept sim``, from the scene's ``calibration``), else the parameters'
``background.calibration_frames``. Every frame is then processed in order; each anchor that a
percept was associated with in a frame gives one row
``frame,id,left,top,width,height,conf,-1,-1,-1`` (frames from 1, the anchor's number as id,
conf 1). One JSON line on stdout sums up, with the time of perception alone per frame (decoding
and writing excluded).

With ``--robot PROFILE`` the camera may have moved: the sequence's recorded joint angles
(``joints.csv`` of ``percept sim``, or an MCAP recording's frame inputs) give each frame's camera
pose through the profile's kinematics, for the calibration and for every frame, and only the
anchors visible in a frame are written (those remembered out of view are not). A ``percept
sim`` folder names its robot's profile (``seqinfo.ini``), which is then used without
``--robot``; otherwise the camera is taken to be still.

Agents are not objects, as in the daemon's world model: an anchor on what came into view moving
(a person walking in) or, with a camera pose per frame, one standing taller on the ground than the
experiment's ``[features] max_object_height`` (:mod:`percept.perception.features.agents`) is left
out of the tracks; ``--agents FILE`` writes its rows there instead.

With a camera pose per frame, an image folder's marker boxes are known objects, as in the daemon:
the markers are searched on every ``[landmarks] every``-th frame of the full image, the boxes
placed from them, and what the frames show of the boxes (their faces and edges) never becomes an
anchor. The marker dictionary, detector and the boxes' ids and sizes are the ``[landmarks]`` of
``--experiment`` (default: the shipped ``tabletop``, whose boxes the shipped scenes and scenarios
place). ``--no-markers`` turns this off; an experiment without boxes, a still camera or a video
or recording has no known objects.
"""

from __future__ import annotations

import argparse
import itertools
import json
import logging
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from percept.runtime.commands import _sequence
from percept.runtime.commands.offline import _perception_params

if TYPE_CHECKING:
    import numpy as np

    from percept.kinematics.camera import CameraModel
    from percept.kinematics.pose import CameraPose
    from percept.perception.features.experience import FeatureSettings
    from percept.perception.landmarks.boxes import BoxEstimator
    from percept.perception.pipeline import FrameResult, Perception
    from percept.perception.segmentation.grid_frame import PerceptionFrame

NAME = "track"
HELP = "track objects in a video, image folder or MOTChallenge sequence; write MOT tracks"

log = logging.getLogger("percept.track")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", help="video file, image folder or MOTChallenge sequence folder")
    p.add_argument("--out", required=True, type=Path, help="tracks file to write (MOT format)")
    _perception_params.add_calibration_arguments(p)
    p.add_argument("--save-background", type=Path, metavar="NPZ", help="save the calibration")
    p.add_argument(
        "--robot",
        metavar="PROFILE",
        help="platform profile (file or shipped name): each frame's camera pose from the "
        "sequence's recorded joint angles (percept sim's joints.csv, or a recording)",
    )
    p.add_argument(
        "--experiment",
        default="tabletop",
        metavar="TOML",
        help="experiment file or shipped name whose [landmarks] (marker dictionary, boxes' ids "
        "and sizes) place the marker boxes, known objects that never become anchors (they need "
        "camera poses, --robot or a percept sim folder, and an image folder), and whose "
        "[features] max_object_height tells agents from objects (default: tabletop)",
    )
    p.add_argument(
        "--agents",
        type=Path,
        metavar="FILE",
        help="write the rows of the anchors judged agents (people and their arms, left out of "
        "--out) to this MOT file",
    )
    p.add_argument(
        "--no-markers",
        action="store_true",
        help="do not search the markers: the marker boxes' faces and edges may become anchors",
    )
    _perception_params.add_arguments(p)


def progress_printer(label: str) -> Callable[[int, int], None]:
    """A ``progress(done, total)`` callback that keeps one line on stderr up to date."""
    tty = sys.stderr.isatty()

    def show(done: int, total: int) -> None:
        if tty:
            end = "\n" if done >= total else ""
            print(f"\r{label}: {done}/{total}", end=end, file=sys.stderr, flush=True)
        elif done == total or done % max(1, total // 4) == 0:
            log.info("%s: %d/%d frames", label, done, total)

    return show


class MovingCamera:
    """The camera of a sequence with recorded joint angles: its intrinsics, and each frame's
    pose in the robot's ground frame by forward kinematics of the profile (None for a frame
    without a joint reading)."""

    def __init__(self, profile: str, sequence: _sequence.Sequence) -> None:
        from percept.config import find
        from percept.config.loader import ConfigError
        from percept.kinematics.camera import CameraModel
        from percept.kinematics.tree import KinematicTree
        from percept.runtime.settings.profile import load_profile

        settings = load_profile(find("robots", profile))
        tree = KinematicTree.from_settings(settings.kinematics)
        width, height = sequence.size()
        self.camera: CameraModel = CameraModel.from_lens(settings.camera.lens, width, height)
        angles = sequence.joint_angles()
        needed = tree.camera_joints
        for k, frame in enumerate(angles, start=1):
            missing = [n for n in needed if frame is not None and n not in frame]
            if missing:
                raise ConfigError(
                    sequence.path,
                    "",
                    f"frame {k} has no angle for joint(s) {', '.join(missing)} of the camera "
                    f"chain of {settings.name}",
                )
        self.poses: list[CameraPose | None] = [
            None if a is None else tree.camera_pose(a) for a in angles
        ]


def calibrated_perception(
    args: argparse.Namespace,
    sequence: _sequence.Sequence,
    moving: MovingCamera | None = None,
) -> Perception:
    """A :class:`~percept.perception.pipeline.Perception` for ``sequence`` with its background
    ready (calibrated with each frame's camera pose when the camera ``moving`` is given)."""
    from percept.perception.pipeline import Perception
    from percept.runtime.settings.experiment import check_calibration_memory

    params = _perception_params.params_from_args(args)
    if args.calibration_frames is not None and args.calibration_frames < 1:
        raise SystemExit("percept: --calibration-frames must be at least 1")
    # the option first, then what the folder says (percept sim writes it), then the parameters
    frames = args.calibration_frames or sequence.calibration_frames
    if frames is not None:
        background = replace(params.background, calibration_frames=frames)
        params = replace(params, background=background)
    width, height = sequence.size()
    perception = Perception(params, width, height, None if moving is None else moving.camera)
    if getattr(args, "background", None):
        perception.load_background(args.background)
    else:
        given = "--calibration-frames" if args.calibration_frames is not None else None
        if given is None and sequence.calibration_frames is not None:
            given = str(sequence.path / "seqinfo.ini")
        source = given or args.params or "(default parameters)"
        check_calibration_memory(params.background, width, height, source, "background")
        n = params.background.calibration_frames
        # the frames as the daemon's camera gives them: on the grid where perception has one
        frames = _posed(sequence.frames(limit=n, step=perception.step), moving)
        images, poses = _unzip(frames)
        perception.calibrate(
            images,
            progress_printer("calibrating"),
            None if moving is None else (p for p in poses if p is not None),
        )
    if getattr(args, "save_background", None):
        perception.save_background(args.save_background)
    return perception


def frame_step(perception: Perception) -> int:
    """The step of the frames ``perception`` takes: its grid's for a background calibrated on
    grid frames, else 1 (full-size frames, as a background saved from those needs)."""
    return perception.step if perception.grid_frames else 1


def _posed(
    frames: Iterable[tuple[str, float, PerceptionFrame | None]], moving: MovingCamera | None
) -> Iterator[tuple[PerceptionFrame, CameraPose | None]]:
    """The decodable images of ``frames`` with their camera poses (None without ``moving``);
    with ``moving`` only those that have one."""
    for k, (_, _, image) in enumerate(frames):
        pose = None if moving is None else moving.poses[k]
        if image is not None and (moving is None or pose is not None):
            yield image, pose


def _unzip(
    pairs: Iterator[tuple[PerceptionFrame, CameraPose | None]],
) -> tuple[Iterator[PerceptionFrame], Iterator[CameraPose | None]]:
    """Two views of one stream of (image, pose) (itertools.tee keeps only what one side has
    read ahead of the other)."""
    a, b = itertools.tee(pairs)
    return (image for image, _ in a), (pose for _, pose in b)


class MarkerBoxes:
    """The marker boxes of a sequence's frames, as the daemon places them: its box estimator fed
    the full-size grey image of every ``[landmarks] every``-th frame (``search_image(index)``,
    from 0) with the frame's camera pose."""

    def __init__(
        self, estimator: BoxEstimator, search_image: Callable[[int], np.ndarray | None]
    ) -> None:
        self.estimator = estimator
        self.search_image = search_image
        self.placed: set[int] = set()
        """The ids of the boxes placed so far."""

    def known(self, index: int, t: float, pose: CameraPose) -> list[np.ndarray]:
        """The known objects of frame ``index`` (from 0) at time ``t``: the corners of the
        boxes placed by the markers of this frame's search (if it is searched) and those
        before."""
        from percept.perception.tracking.known import marker_boxes

        if index % self.estimator.settings.every == 0:
            image = self.search_image(index)
            if image is not None:
                self.estimator.observe(self.estimator.search(image, pose), pose, t)
                self.placed.update(b.id for b in self.estimator.boxes(t))
        return marker_boxes(self.estimator, t)


def known_marker_boxes(
    args: argparse.Namespace,
    sequence: _sequence.Sequence,
    moving: MovingCamera | None,
    step: int,
) -> MarkerBoxes | None:
    """The marker boxes of ``--experiment`` for ``sequence`` (its frames read for perception's
    grid of ``step``), or None (saying why) where they cannot be placed: ``--no-markers``, no
    camera poses, not an image folder, no boxes."""
    from percept.perception.landmarks.boxes import BoxEstimator
    from percept.runtime.settings.experiment import load_experiment

    if args.no_markers:
        return None
    if moving is None or sequence.images is None:
        log.info("no marker boxes: they need camera poses (--robot) and an image folder")
        return None
    landmarks = load_experiment(args.experiment).landmarks
    if not landmarks.boxes:
        log.info("no marker boxes: %s has no [[landmarks.boxes]]", args.experiment)
        return None
    estimator = BoxEstimator(landmarks, moving.camera)
    return MarkerBoxes(estimator, lambda index: sequence.search_image(index, step))


class Agents:
    """Which anchors are agents, judged frame by frame as the daemon judges them
    (:class:`~percept.perception.features.agents.ObjectsAndAgents`): the height on the ground
    comes from each anchor's sensory experience, so it needs the ``camera`` and a pose per frame;
    without them only what came into view moving is an agent."""

    def __init__(
        self, settings: FeatureSettings, width: int, height: int, camera: CameraModel | None
    ) -> None:
        from percept.perception.features.agents import AgentJudge, ObjectsAndAgents
        from percept.perception.features.experience import SensoryMemory

        memory = None if camera is None else SensoryMemory(camera, settings)
        judge = AgentJudge(settings.max_object_height, width, height)
        self.sorting = ObjectsAndAgents(judge, memory)
        self.ids: set[str] = set()
        """Every anchor judged an agent in some frame."""

    def of_frame(
        self, result: FrameResult, pose: CameraPose | None, turn: np.ndarray | None
    ) -> set[str]:
        """The ids of the agents among ``result``'s anchors, seen from ``pose``; ``turn``: the
        view's change since the last frame (None: the camera did not turn)."""
        agents = {s.anchor.id for s in self.sorting.sort(result, pose, turn) if s.reason}
        self.ids |= agents
        return agents


@dataclass
class Tracks:
    """What :func:`track_frames` gives: MOT rows of the objects' anchors and of the agents'
    (frames from 1), perception seconds per frame, and frames skipped."""

    rows: list[str]
    agent_rows: list[str]
    times: list[float]
    skipped: int


def track_frames(
    perception: Perception,
    frames: Iterable[tuple[float, PerceptionFrame | None]],
    poses: list[CameraPose | None] | None = None,
    boxes: MarkerBoxes | None = None,
    agents: Agents | None = None,
) -> Tracks:
    """The visible anchors of each frame as MOT rows, those ``agents`` judges agents apart.

    ``frames`` yields ``(t, image)``; ``poses`` holds each frame's camera pose (None: a still
    camera); ``boxes`` places the marker boxes, known objects (with a pose only). The marker
    search and the agents' judgement are not counted in the perception seconds (the daemon runs
    the search on a thread of its own, the judgement with the sensory experiences).
    """
    from percept.perception.evaluation.tracking import mot_box

    tracks = Tracks([], [], [], 0)
    for index, (t, image) in enumerate(frames, start=1):
        pose = None if poses is None else poses[index - 1]
        known = [] if boxes is None or pose is None else boxes.known(index - 1, t, pose)
        start = time.perf_counter()
        result = perception.process(image, t, pose, known=known)  # type: ignore[arg-type]  # None: skipped, logged
        tracks.times.append(time.perf_counter() - start)
        tracks.skipped += result.skipped
        if result.skipped:
            continue
        turn = perception.tracker.turn
        agent_ids = set() if agents is None else agents.of_frame(result, pose, turn)
        for a in result.anchors:
            if a.visible:
                left, top, w, h = mot_box(a.bbox)
                row = f"{index},{a.number},{left:.2f},{top:.2f},{w:.2f},{h:.2f},1,-1,-1,-1"
                (tracks.agent_rows if a.id in agent_ids else tracks.rows).append(row)
    return tracks


def _profile_of(sequence: _sequence.Sequence) -> str | None:
    """Without ``--robot``: the profile a ``percept sim`` folder names for its joint angles
    (the camera may have moved), or None (a still camera), saying why when there are joint
    angles all the same."""
    profile = sequence.recorded_profile()
    if profile is not None:
        log.info(
            "camera poses from %s/joints.csv with the robot profile %s that its seqinfo.ini "
            "names (--robot to give another)",
            sequence.path,
            profile,
        )
    elif sequence.images is not None and (sequence.path / "joints.csv").is_file():
        log.warning(
            "%s/joints.csv holds the joint angles but seqinfo.ini names no robot profile "
            "(written by an older percept sim): the camera is taken to be still; give "
            "--robot PROFILE to use them",
            sequence.path,
        )
    return profile


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from percept.runtime.settings.experiment import load_experiment

    sequence = _sequence.open_sequence(args.source)
    profile = args.robot or _profile_of(sequence)
    moving = None if profile is None else MovingCamera(profile, sequence)
    perception = calibrated_perception(args, sequence, moving)
    poses = None if moving is None else moving.poses
    step = frame_step(perception)
    frames = ((t, im) for _, t, im in sequence.frames(step=step))
    boxes = known_marker_boxes(args, sequence, moving, step)
    features = load_experiment(args.experiment).features
    agents = Agents(
        features, perception.width, perception.height, None if moving is None else moving.camera
    )
    tracks = track_frames(perception, frames, poses, boxes, agents)
    for path, rows in ((args.out, tracks.rows), (args.agents, tracks.agent_rows)):
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text("".join(r + "\n" for r in rows), encoding="utf-8")
    times = tracks.times
    ms = np.array(times) * 1e3 if times else np.zeros(1)
    summary = {
        "source": str(args.source),
        "out": str(args.out),
        "frames": len(times),
        "skipped_frames": tracks.skipped,
        "width": perception.width,
        "height": perception.height,
        "rows": len(tracks.rows),
        "agent_rows": len(tracks.agent_rows),
        "anchors_created": perception.tracker.created_count,
        "agents": len(agents.ids),
        "calibration_frames": None
        if getattr(args, "background", None)
        else perception.params.background.calibration_frames,
        "camera_poses": 0 if poses is None else sum(p is not None for p in poses),
        "marker_boxes": 0 if boxes is None else len(boxes.placed),
        "ms_per_frame_median": round(float(np.median(ms)), 4),
        "ms_per_frame_p90": round(float(np.percentile(ms, 90)), 4),
        "ms_per_frame_mean": round(float(np.mean(ms)), 4),
    }
    print(json.dumps(summary))
    return 0
