"""Head calibration's maths on synthetic sightings: a perturbed head seen through its profile is
recovered, what cannot be separated is folded or refused by name."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from percept.kinematics.calibration import (
    CalibrationRefused,
    HeadCalibration,
    MarkerOnBody,
    Readings,
    Sighting,
    calibrate_head,
    corrected_mount,
    corrected_origin,
)
from percept.kinematics.camera import CameraModel
from percept.kinematics.gaze import Limits, sweep_grid, sweep_keyframes
from percept.kinematics.pose import (
    FACE_YAW,
    axis_angle_matrix,
    ground_transform,
    marker_on_box,
    matrix_rpy,
    transform,
)
from percept.kinematics.settings import JointSpec, KinematicsSettings
from percept.kinematics.tree import KinematicTree

LENS = CameraModel.from_opening_angles(1.0472, 0.8172, 320, 240)
ZERO = {"head_pan": math.radians(3), "head_tilt": math.radians(-2)}
MOUNT = transform((0.004, -0.003, 0.0), (0.0, 0.0244, -0.0244))
DELAY = 0.03
BOXES = {1: (1.1, 0.3, math.pi), 2: (0.82, 0.43, math.pi / 2)}


def _tree() -> KinematicTree:
    """The MYON profile's head (config/robots/myon.toml)."""
    return KinematicTree.from_settings(
        KinematicsSettings(
            camera_link="camera",
            root_link="torso",
            ground_xyz=(0.0, 0.0, 0.8),
            joints=(
                JointSpec("head_pan", "torso", "neck", xyz=(0, 0, 0.26), axis=(0, 0, 1)),
                JointSpec("head_tilt", "neck", "head", xyz=(0, 0, 0.05), axis=(0, -1, 0)),
                JointSpec("camera_mount", "head", "camera", "fixed", xyz=(0.07, 0, 0.06)),
            ),
        )
    )


def _markers() -> dict[int, MarkerOnBody]:
    h = 0.05
    square = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
    out = {}
    for box in BOXES:
        for k, face in enumerate(FACE_YAW):
            T = marker_on_box((0.18, 0.18, 0.18), face, (0.0, 0.0), 0.0)
            mid = 4 * (box - 1) + k
            out[mid] = MarkerOnBody(mid, box, square @ T[:3, :3].T + T[:3, 3])
    return out


def _sweep(
    tree: KinematicTree, steps: tuple[int, int] = (4, 3), noise: float = 0.2, dwell: float = 0.3
) -> tuple[list[Sighting], Readings]:
    """What the perturbed head sees and reads sweeping over the boxes, at 15 fps."""
    limits = {"head_pan": Limits(0.0, 0.75), "head_tilt": Limits(-0.95, -0.55)}
    keys = sweep_keyframes(sweep_grid(limits, steps=steps), speed=0.5, dwell=dwell)
    end = max(k[-1][0] for k in keys.values())

    def motion(t: np.ndarray) -> dict[str, np.ndarray]:
        return {n: np.interp(t, [a for a, _ in k], [b for _, b in k]) for n, k in keys.items()}

    rng = np.random.default_rng(1)
    markers = _markers()
    sightings = []
    for t in np.arange(0.0, end, 1 / 15):
        body = {n: float(a[0]) - ZERO[n] for n, a in motion(np.array([t])).items()}
        pose = tree.camera_pose(body)
        to_camera = np.linalg.inv(pose.matrix() @ MOUNT)
        for m in markers.values():
            placed = ground_transform(*BOXES[m.body])
            p = m.corners @ placed[:3, :3].T + placed[:3, 3]
            c = m.corners
            normal = placed[:3, :3] @ np.cross(c[1] - c[0], c[3] - c[0])
            if normal @ (pose.t - p.mean(axis=0)) <= 0:
                continue  # the marker turns its back on the camera
            uv = LENS.project(p @ to_camera[:3, :3].T + to_camera[:3, 3])
            if np.isfinite(uv).all() and LENS.contains(uv).all():
                sightings.append(Sighting(float(t), m.id, uv + rng.normal(0, noise, uv.shape)))
    times = np.arange(0.0, end + 0.5, 0.02)
    step = 2 * math.pi / 4096
    readings = {n: np.round(a / step) * step for n, a in motion(times - DELAY).items()}
    return sightings, Readings(times, readings)


def _measured() -> dict[int, np.ndarray]:
    return {b: ground_transform(*p) for b, p in BOXES.items()}


@pytest.fixture(scope="module")
def swept() -> tuple[KinematicTree, list[Sighting], Readings]:
    tree = _tree()
    return (tree, *_sweep(tree))


def _pose_error(tree: KinematicTree, result: HeadCalibration, corrected: KinematicTree) -> float:
    """The largest camera position error (m) of the corrected chain over a few head poses."""
    errors = []
    for pan, tilt in ((0.1, -0.8), (0.6, -0.6), (-0.4, 0.2)):
        body = {"head_pan": pan - ZERO["head_pan"], "head_tilt": tilt - ZERO["head_tilt"]}
        truth = tree.camera_pose(body).matrix() @ MOUNT
        got = corrected.camera_pose({"head_pan": pan, "head_tilt": tilt}).matrix()
        errors.append(float(np.linalg.norm(got[:3, 3] - truth[:3, 3])))
    return max(errors)


def test_a_perturbed_head_is_recovered(swept) -> None:
    tree, sightings, readings = swept
    result = calibrate_head(tree, LENS, sightings, readings, _markers(), _measured())
    assert result.folded == ("head_tilt",)
    assert abs(result.joint_zero["head_pan"].value - ZERO["head_pan"]) < math.radians(0.2)
    assert abs(result.delay.value - DELAY) < 0.005
    # The tilt's zero is the camera turned about the tilt axis: compare with the same mounting.
    head = tree.link_transform("head", {})
    to_camera = np.linalg.inv(head) @ tree.camera_pose({}).matrix()
    turn = np.eye(4)
    turn[:3, :3] = axis_angle_matrix((0.0, -1.0, 0.0), -ZERO["head_tilt"])
    same = np.linalg.inv(to_camera) @ turn @ to_camera @ MOUNT
    found = result.mounting()
    # Encoder ticks (0.09 deg) at the sweep's poses cost the mounting's position about 2 mm.
    assert np.linalg.norm(found[:3, 3] - same[:3, 3]) < 0.004
    angle = math.acos(min(1.0, (np.trace(found[:3, :3].T @ same[:3, :3]) - 1) / 2))
    assert math.degrees(angle) < 0.2
    assert result.reprojection_px_after < 0.5 < 10 < result.reprojection_px_before
    assert all(e.sigma > 0 for e in (*result.camera_offset, result.delay))
    # The corrected chain: the pan's origin turned back by its zero, the camera joint moved.
    name, mount = corrected_mount(tree, result.mounting())
    pan = corrected_origin(tree, "head_pan", result.joint_zero["head_pan"].value)
    joints = []
    for j in tree.joints:
        T = {name: mount, "head_pan": pan}.get(j.name)
        if T is not None:
            j = dataclasses.replace(j, xyz=tuple(T[:3, 3]), rpy=matrix_rpy(T[:3, :3]))
        joints.append(j)
    assert _pose_error(tree, result, KinematicTree(tree.settings, joints)) < 0.003
    assert _pose_error(tree, result, tree) > 0.006  # the profile as it was


def test_too_few_markers_are_refused(swept) -> None:
    tree, sightings, readings = swept
    with pytest.raises(CalibrationRefused, match="too few markers") as err:
        calibrate_head(tree, LENS, sightings[:5], readings, _markers(), _measured())
    assert err.value.parameters == ("markers",)


def test_an_unmeasured_world_leaves_the_pan_zero_undetermined(swept) -> None:
    tree, sightings, readings = swept
    with pytest.raises(CalibrationRefused, match=r"joint_zero\.head_pan is undetermined"):
        calibrate_head(tree, LENS, sightings, readings, _markers(), {})


def test_a_head_that_never_moves_leaves_the_delay_undetermined() -> None:
    tree = _tree()
    sightings, readings = _sweep(tree, steps=(1, 1), dwell=3.0)
    with pytest.raises(CalibrationRefused, match="undetermined") as err:
        calibrate_head(tree, LENS, sightings, readings, _markers(), _measured())
    assert "delay" in err.value.parameters


def test_a_sweep_that_never_tilts_leaves_the_pan_zero_undetermined() -> None:
    # With the tilt still, turning the pan's zero is turning the camera on its link.
    tree = _tree()
    sightings, readings = _sweep(tree, steps=(5, 1))
    with pytest.raises(CalibrationRefused, match="undetermined") as err:
        calibrate_head(tree, LENS, sightings, readings, _markers(), _measured())
    assert "joint_zero.head_pan" in err.value.parameters
