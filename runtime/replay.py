"""Replaying a recording through the daemon's pipeline.

The recorded frames, with the joint angles and peer messages each one was processed with, go
through a fresh :class:`~runtime.pipeline.Pipeline` built from the recorded robot's profile and
experiment (or others given) and the recorded background model. The pipeline reads no clock, so a
replay gives the same world models every time; with images recorded raw (``--raw-images``) they
are exactly the ones the daemon published, with JPEG images they differ by what the compression
changed in the pixels.
"""

from __future__ import annotations

import json
import logging
import tempfile
import time
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from runtime.recording import BACKGROUND_ATTACHMENT, Recording, read_recording

log = logging.getLogger("percept.replay")


@dataclass
class ReplayReport:
    """What a replay did: frames replayed, and how its world models compare to the recorded ones
    (``matched``: equal in every field; ``differing``: frame numbers of the others)."""

    frames: int = 0
    recorded_worlds: int = 0
    matched: int = 0
    differing: list[int] = field(default_factory=list)
    truncated: bool = False
    seconds: float = 0.0
    ms_per_frame: list[float] = field(default_factory=list, repr=False)

    def summary(self) -> dict[str, Any]:
        ms = sorted(self.ms_per_frame)
        return {
            "frames": self.frames,
            "recorded_worlds": self.recorded_worlds,
            "matched": self.matched,
            "differing": len(self.differing),
            "first_differing": self.differing[:5],
            "truncated": self.truncated,
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
) -> Iterator[dict[str, Any]]:
    """Replay ``path``; yields each replayed world model. ``speed`` None: as fast as possible,
    else paced by the recorded frame times divided by ``speed``. ``report`` (if given) is filled
    in as the replay goes, including the comparison with the recorded world models."""
    from runtime.daemon import DaemonSettings
    from runtime.experiment import load_experiment
    from runtime.pipeline import RECENT_FRAMES, FrameInputs, Pipeline
    from runtime.profile import load_profile

    report = report if report is not None else ReplayReport()
    recording = Recording(Path(path))
    pipeline: Pipeline | None = None
    images: OrderedDict[int, Any] = OrderedDict()  # recent frames and camera poses, to search
    replayed: dict[int, str] = {}
    recorded: dict[int, str] = {}
    began = time.monotonic()
    first: tuple[float, float] | None = None  # (recorded t, replay clock) of the first frame
    for kind, item in read_recording(path, recording):
        if kind == "world":
            recorded[item["frame"]] = _canonical(item)
            _compare(item["frame"], replayed, recorded, report)
            continue
        if kind != "frame":
            continue
        inputs = FrameInputs.from_record(item.inputs)
        if pipeline is None:
            meta = recording.metadata
            profile = load_profile(profile_path or meta["profile"])
            experiment = load_experiment(experiment_path or meta["experiment"])
            settings: DaemonSettings = experiment.daemon
            height, width = item.image.shape[:2]
            pipeline = Pipeline(
                meta.get("robot", "replay"),
                profile,
                experiment,
                width,
                height,
                joint_max_age=settings.joint_max_age,
            )
            _load_background(pipeline, recording)
        if speed is not None:
            if first is None:
                first = (inputs.t, time.monotonic())
            due = first[1] + (inputs.t - first[0]) / speed
            time.sleep(max(0.0, due - time.monotonic()))
        t0 = time.perf_counter()
        # The frames whose marker search the daemon applied here are searched again now.
        markers = {
            seq: pipeline.boxes.search(*images[seq])
            for seq in inputs.marker_frames
            if seq in images
        }
        out = pipeline.step(item.image, inputs, markers)
        images[inputs.seq] = (item.image, None if out.pose is None else out.pose.pose)
        while len(images) > RECENT_FRAMES:
            images.popitem(last=False)
        report.ms_per_frame.append((time.perf_counter() - t0) * 1000)
        report.frames += 1
        replayed[inputs.seq] = _canonical(out.world)
        _compare(inputs.seq, replayed, recorded, report)
        yield out.world
    report.recorded_worlds = len(recorded) + report.matched + len(report.differing)
    report.truncated = recording.truncated
    report.seconds = time.monotonic() - began


def _canonical(world: dict[str, Any]) -> str:
    """A world model as the JSON it is sent and recorded as (so floats compare as recorded)."""
    return json.dumps(world, sort_keys=True)


def _compare(frame: int, replayed: dict[int, str], recorded: dict[int, str], report) -> None:
    if frame in replayed and frame in recorded:
        if replayed.pop(frame) == recorded.pop(frame):
            report.matched += 1
        else:
            report.differing.append(frame)


def _load_background(pipeline: Any, recording: Recording) -> None:
    data = recording.attachments.get(BACKGROUND_ATTACHMENT)
    if data is None:
        raise ValueError(f"{recording.path}: no background model recorded; cannot replay")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / BACKGROUND_ATTACHMENT
        path.write_bytes(data)
        pipeline.load_background(path)
