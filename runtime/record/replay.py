"""Replaying a recording through the daemon's pipeline.

The recorded frames, with the joint angles and peer messages each one was processed with, go
through a fresh :class:`~percept.runtime.daemon.pipeline.Pipeline` built from the recorded robot's
profile and experiment (or others given) and the recorded background model. The pipeline reads no
clock, so a replay gives the same world models every time; with images recorded raw
(``--raw-images``) they are exactly the ones the daemon published, with JPEG images they differ by
what the compression changed in the pixels.
"""

from __future__ import annotations

import json
import logging
import tempfile
import time
from collections import OrderedDict
from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from percept.runtime.net.codec import JSON
from percept.runtime.net.messages import document
from percept.runtime.record.reader import (
    RecordedFrame,
    Recording,
    RecordingError,
    read_recording,
)
from percept.runtime.record.topics import BACKGROUND_ATTACHMENT

if TYPE_CHECKING:
    from percept.kinematics.pose import CameraPose
    from percept.perception.landmarks.detection.detector import Marker
    from percept.perception.segmentation.grid_frame import PerceptionFrame
    from percept.runtime.daemon.pipeline import FrameInputs, Pipeline

log = logging.getLogger("percept.replay")


@dataclass
class ReplayReport:
    """What a replay did: frames replayed, how its world models compare to the recorded ones
    (``matched``: equal in every field; ``differing``: frame numbers of the others), and what
    of the file was damaged and skipped (``damaged``: chunks, records, bytes, messages)."""

    frames: int = 0
    recorded_worlds: int = 0
    matched: int = 0
    differing: list[int] = field(default_factory=list)
    truncated: bool = False
    damaged: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    image_format: str | None = None
    """How the images were recorded: ``jpeg`` (lossy) or ``bgr8`` (exact)."""
    ms_per_frame: list[float] = field(default_factory=list, repr=False)

    def note(self) -> str | None:
        """Why world models differ when that is expected: JPEG images are not the frames the
        daemon saw."""
        if self.differing and self.image_format not in (None, "bgr8"):
            return (
                f"expected: the images were recorded as {self.image_format} (lossy), so the "
                "replayed frames are not the ones the daemon saw and world models differ; record "
                "with --raw-images for replays that match"
            )
        return None

    def summary(self) -> dict[str, JSON]:
        ms = sorted(self.ms_per_frame)
        return {
            "frames": self.frames,
            "recorded_worlds": self.recorded_worlds,
            "matched": self.matched,
            "differing": len(self.differing),
            "first_differing": [*self.differing[:5]],
            "images": self.image_format,
            "note": self.note(),
            "truncated": self.truncated,
            "damaged": {**self.damaged},
            "seconds": round(self.seconds, 3),
            "ms_per_frame_median": round(ms[len(ms) // 2], 3) if ms else None,
        }


def replay(
    path: str | Path,
    *,
    profile_path: str | Path | None = None,
    experiment_path: str | Path | None = None,
    speed: float | None = 1.0,
    report: ReplayReport | None = None,
) -> Iterator[dict[str, JSON]]:
    """Replay ``path``; yields each replayed world model, as the JSON it is sent and recorded as.
    ``speed`` None: as fast as possible, else paced by the recorded frame times divided by
    ``speed``. ``report`` (if given) is filled in as the replay goes, including the comparison
    with the recorded world models."""
    from percept.runtime.daemon.pipeline import FrameInputs

    report = report if report is not None else ReplayReport()
    recording = Recording(Path(path))
    replayer: _Replayer | None = None
    replayed: dict[int, dict[str, JSON]] = {}
    recorded: dict[int, dict[str, JSON]] = {}
    began = time.monotonic()
    first: tuple[float, float] | None = None  # (recorded t, replay clock) of the first frame
    for kind, item in read_recording(path, recording):
        if kind == "world":
            recorded[item["frame"]] = item
            _compare(item["frame"], replayed, recorded, report)
            continue
        if kind != "frame":
            continue
        inputs = FrameInputs.from_record(item.inputs)
        if replayer is None:
            pipeline = _pipeline(path, recording, item, profile_path, experiment_path)
            replayer = _Replayer(pipeline)
        if speed is not None:
            if first is None:
                first = (inputs.t, time.monotonic())
            due = first[1] + (inputs.t - first[0]) / speed
            time.sleep(max(0.0, due - time.monotonic()))
        world = replayer.step(item, inputs, report)
        if world is None:  # the daemon recorded no world model for it either
            continue
        replayed[inputs.seq] = world
        _compare(inputs.seq, replayed, recorded, report)
        yield world
    report.recorded_worlds = len(recorded) + report.matched + len(report.differing)
    _report_damage(report, recording)
    report.seconds = time.monotonic() - began


def _pipeline(
    path: str | Path,
    recording: Recording,
    first: RecordedFrame,
    profile_path: str | Path | None,
    experiment_path: str | Path | None,
) -> Pipeline:
    """A fresh pipeline for the recorded robot (profile and experiment as recorded, unless
    given), sized to the ``first`` frame, with the recorded background model."""
    from percept.runtime.daemon.pipeline import Pipeline
    from percept.runtime.daemon.settings import DaemonSettings
    from percept.runtime.settings.experiment import load_experiment
    from percept.runtime.settings.profile import load_profile

    meta = recording.metadata
    if not (profile_path or "profile" in meta) or not (experiment_path or "experiment" in meta):
        raise RecordingError(
            f"{path}: the recording's metadata is missing or damaged; give --robot and --experiment"
        )
    profile = load_profile(profile_path or _recorded_file(path, meta, "robots", "--robot"))
    experiment = load_experiment(
        experiment_path or _recorded_file(path, meta, "experiments", "--experiment")
    )
    settings: DaemonSettings = experiment.daemon
    height, width = first.image.shape[:2]
    pipeline = Pipeline(
        meta.get("robot", "replay"),
        profile,
        experiment,
        width,
        height,
        joint_max_age=settings.joint_max_age,
    )
    _load_background(pipeline, recording)
    return pipeline


def _recorded_file(path: str | Path, meta: dict[str, str], kind: str, option: str) -> str:
    """The recorded profile or experiment (``kind``) as :func:`percept.config.find` takes it. A
    shipped file is recorded by name; recordings made before that hold the shipped name as a
    path in the folder the robot ran in (``<folder>/tabletop``), found here by its name."""
    from percept.config import KINDS, shipped

    recorded = meta["profile" if kind == "robots" else "experiment"]
    stored = Path(recorded)
    if len(stored.parts) == 1 or stored.is_file():
        return recorded
    if stored.suffix == "" and stored.name in shipped(kind):
        return stored.name
    raise RecordingError(
        f"{path}: recorded with the {KINDS[kind]} {recorded}, which is not there any more; "
        f"give it with {option} FILE"
    )


class _Replayer:
    """The pipeline stepped through recorded frames, with the recent frames and camera poses
    kept for the marker searches the daemon applied frames later."""

    def __init__(self, pipeline: Pipeline) -> None:
        self.pipeline = pipeline
        self._recent: OrderedDict[int, tuple[np.ndarray, CameraPose | None]] = OrderedDict()

    def _perceived(self, image: np.ndarray) -> PerceptionFrame:
        """A recorded image as perception takes it: a background calibrated on grid frames
        takes the image's block averages on the grid (as a folder of JPEG files or a raw camera
        gave them, to rounding: a replay of such a run is close, not exact)."""
        from percept.drivers.camera.decode import area_grid
        from percept.perception.segmentation.grid_frame import GridFrame

        perception = self.pipeline.perception
        if not perception.grid_frames:
            return image
        return GridFrame.of(area_grid(image, perception.step), perception.step)

    def step(
        self, frame: RecordedFrame, inputs: FrameInputs, report: ReplayReport
    ) -> dict[str, JSON] | None:
        """The frame's world model as its JSON (None: the pipeline made none)."""
        from percept.runtime.daemon.pipeline import RECENT_FRAMES

        t0 = time.perf_counter()
        # The frames whose marker search the daemon applied here are searched again now.
        markers: dict[int, list[Marker]] = {
            seq: self.pipeline.boxes.search(*self._recent[seq])
            for seq in inputs.marker_frames
            if seq in self._recent
        }
        out = self.pipeline.step(self._perceived(frame.image), inputs, markers)
        report.image_format = frame.image_format
        self._recent[inputs.seq] = (frame.image, None if out.pose is None else out.pose.pose)
        while len(self._recent) > RECENT_FRAMES:
            self._recent.popitem(last=False)
        report.ms_per_frame.append((time.perf_counter() - t0) * 1000)
        report.frames += 1
        return None if out.world is None else document(out.world)


def _report_damage(report: ReplayReport, recording: Recording) -> None:
    report.truncated = recording.truncated
    damage = recording.damage
    report.damaged = {
        "chunks": damage.chunks,
        "records": damage.records,
        "bytes": damage.bytes,
        "messages": damage.messages,
    }


def _canonical(world: dict[str, JSON]) -> str:
    """A world model as the JSON it is sent and recorded as (so floats compare as recorded)."""
    return json.dumps(world, sort_keys=True)


def _as_recorded(world: dict[str, JSON], schema: JSON, keys: Collection[str]) -> dict[str, JSON]:
    """A replayed world model as a recording of ``schema`` with the top-level ``keys`` has it:
    ``percept.world/1`` objects have no ``visible`` and ``last_seen``; a recording made before
    world models reported ``agents`` has none."""
    if "agents" not in keys:
        world = {k: v for k, v in world.items() if k != "agents"}
    objects = world.get("objects")
    if schema != "percept.world/1" or not isinstance(objects, list):
        return world
    old = [
        {k: v for k, v in o.items() if k not in ("visible", "last_seen")}
        for o in objects
        if isinstance(o, dict)
    ]
    return {**world, "schema": schema, "objects": old}  # type: ignore[dict-item]


def _compare(
    frame: int,
    replayed: dict[int, dict[str, JSON]],
    recorded: dict[int, dict[str, JSON]],
    report: ReplayReport,
) -> None:
    if frame in replayed and frame in recorded:
        old = recorded.pop(frame)
        new = _as_recorded(replayed.pop(frame), old.get("schema"), old.keys())
        if _canonical(new) == _canonical(old):
            report.matched += 1
        else:
            report.differing.append(frame)


def _load_background(pipeline: Pipeline, recording: Recording) -> None:
    data = recording.attachments.get(BACKGROUND_ATTACHMENT)
    if data is None:
        raise RecordingError(
            f"{recording.path}: no background model in the recording (not recorded or damaged); "
            "cannot replay"
        )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / BACKGROUND_ATTACHMENT
        path.write_bytes(data)
        pipeline.load_background(path)
