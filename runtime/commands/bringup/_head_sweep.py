"""What head calibration reads: marker sightings and joint readings over a sweep of the head, in
the simulated world or from a recording, and the experiment's markers on their boxes."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from percept.kinematics.calibration import MarkerOnBody, Readings, Sighting
from percept.kinematics.gaze import Limits, sweep_keyframes
from percept.kinematics.pose import ground_transform, invert
from percept.perception.landmarks.detection.detector import MarkerDetector
from percept.perception.landmarks.geometry import marker_in_box, marker_object_points
from percept.perception.landmarks.settings import LandmarkSettings
from percept.runtime.settings.profile import PlatformProfile

#: An image's degradation before detection (a webcam's blur and JPEG in the bench), or None.
Degrade = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Sweep:
    """What the sweep saw: marker sightings, joint readings, and how long it took (s)."""

    sightings: list[Sighting]
    readings: Readings
    duration: float
    frames: int


def box_markers(landmarks: LandmarkSettings) -> dict[int, MarkerOnBody]:
    """Every marker of the experiment's boxes, its corners in its box's frame."""
    out: dict[int, MarkerOnBody] = {}
    for box in landmarks.boxes:
        for m in box.markers:
            T = marker_in_box(box, m)
            corners = marker_object_points(m.side) @ T[:3, :3].T + T[:3, 3]
            out[m.id] = MarkerOnBody(id=m.id, body=box.id, corners=corners)
    return out


def head_limits(profile: PlatformProfile, joints: Sequence[str]) -> dict[str, Limits]:
    """The servo limits of the gaze ``joints`` that the profile has servos for."""
    servos = {j.name: j for j in profile.joints}
    return {n: Limits(servos[n].min, servos[n].max) for n in joints if n in servos}


def sim_sweep(
    scene_path: Path,
    robot: str,
    profile: PlatformProfile,
    landmarks: LandmarkSettings,
    poses: list[dict[str, float]],
    speed: float,
    fps: float,
    dwell: float = 0.3,
    degrade: Degrade | None = None,
) -> tuple[Sweep, dict[int, np.ndarray]]:
    """Robot ``robot`` of the scene sweeps its head through ``poses`` (moving at ``speed``
    rad/s, resting ``dwell`` s at each); its camera's frames at ``fps`` are searched for the
    experiment's markers, its joints read at the profile's bus rate (in encoder ticks). Also
    returns each box's pose in the robot's ground frame as the scene places it (what a lab
    measures with a tape)."""
    from percept.drivers.sim.scene import JointMotion
    from percept.drivers.sim.world import SimWorld
    from percept.runtime.settings.scene import load_scene

    scene, platforms = load_scene(scene_path)
    me = scene.robot(robot)
    keyframes = sweep_keyframes(poses, speed, dwell)
    motion = {n: JointMotion(keyframes=tuple(k)) for n, k in keyframes.items()}
    moving = dataclasses.replace(me, joints={**me.joints, **motion})
    scene = dataclasses.replace(
        scene, robots=tuple(moving if r.name == robot else r for r in scene.robots)
    )
    duration = max(k[-1][0] for k in keyframes.values())
    detector = MarkerDetector.from_settings(landmarks)
    sightings: list[Sighting] = []
    frames = int(duration * fps) + 1
    with SimWorld(scene, platforms) as world:
        for k in range(frames):
            t = k / fps
            image = world.render(robot, t)
            if degrade is not None:
                image = degrade(image)
            sightings += [Sighting(t, m.id, m.corners) for m in detector.detect(image)]
        ticks = {j.name: 2 * math.pi / j.ticks_per_rev for j in profile.joints}
        times = np.arange(0.0, duration + 0.5, 1.0 / profile.bus.rate)
        rows = [world.joint_readings(robot, float(t)) for t in times]
    angles = {
        n: np.round(np.array([r[n] for r in rows]) / step) * step
        for n, step in ticks.items()
        if n in rows[0]
    }
    to_robot = invert(ground_transform(*me.pose))
    boxes = {b.id: to_robot @ ground_transform(*b.pose) for b in scene.boxes}
    return Sweep(sightings, Readings(times, angles), duration, frames), boxes


def recorded_sweep(path: Path, landmarks: LandmarkSettings) -> Sweep:
    """The sweep in a recording (``percept run --record``): each frame's markers, and the joint
    angles recorded with each frame as the joint readings."""
    from percept.runtime.record.reader import RecordedFrame, read_recording

    detector = MarkerDetector.from_settings(landmarks)
    sightings: list[Sighting] = []
    times: list[float] = []
    rows: list[dict[str, float]] = []
    for kind, item in read_recording(path):
        if kind != "frame" or not isinstance(item, RecordedFrame):
            continue
        t, joints = item.inputs.get("t"), item.inputs.get("joints")
        if not isinstance(t, int | float) or not isinstance(joints, dict):
            continue
        angles = {n: float(a) for n, a in joints.items() if isinstance(a, int | float)}
        if times and t <= times[-1]:
            continue
        times.append(float(t))
        rows.append(angles)
        sightings += [Sighting(float(t), m.id, m.corners) for m in detector.detect(item.image)]
    names = set.intersection(*(set(r) for r in rows)) if rows else set()
    readings = Readings(
        np.asarray(times), {n: np.array([r[n] for r in rows]) for n in sorted(names)}
    )
    duration = times[-1] - times[0] if times else 0.0
    return Sweep(sightings, readings, duration, len(times))
