"""The simulated robot built off its profile on purpose, and ``percept calibrate-head`` /
``percept check-pose`` on it: a short low-resolution sweep recovers the perturbation, the
corrected profile is written next to the original (which is unchanged), refusals exit 2."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from percept.config.loader import ConfigError
from percept.drivers.sim.scene import JointMotion
from percept.drivers.sim.world import SimWorld
from percept.kinematics.tree import KinematicTree
from percept.runtime.cli import main
from percept.runtime.settings.profile import load_profile
from percept.runtime.settings.scene import load_scene, open_world

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "config" / "scenes" / "tabletop-myon-perturbed.toml"
PROFILE = REPO / "config" / "robots" / "myon.toml"
SWEEP = ["--pan", "0.0", "0.75", "--tilt", "-0.9", "-0.5", "--steps", "3", "2", "--fps", "8"]


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 320x240 MYON profile and the perturbed scene with both robots on it."""
    root = tmp_path_factory.mktemp("lab")
    text = PROFILE.read_text(encoding="utf-8")
    text = text.replace("width = 640\nheight = 480", "width = 320\nheight = 240")
    assert "width = 320" in text
    (root / "robots").mkdir()
    (root / "robots" / "myon.toml").write_text(text, encoding="utf-8")
    (root / "scenes").mkdir()
    scene = SCENE.read_text(encoding="utf-8").replace(
        'profile = "../robots/myon.toml"', f'profile = "{root / "robots" / "myon.toml"}"'
    )
    (root / "scenes" / "perturbed.toml").write_text(scene, encoding="utf-8")
    return root


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_the_perturbed_world_renders_the_camera_off_its_profile() -> None:
    scene, platforms = load_scene(SCENE)
    a = scene.robot("a")
    pan = JointMotion(amplitude=0.4, period=4.0)
    a = dataclasses.replace(a, joints={**a.joints, "head_pan": pan})
    scene = dataclasses.replace(scene, robots=(a, *scene.robots[1:]))
    tree = KinematicTree.from_settings(platforms["a"].kinematics)
    truth = a.perturb
    with SimWorld(scene, platforms) as world:
        for t in (0.5, 1.3, 2.2):
            read = world.joint_readings("a", t)
            assert read["head_pan"] == pytest.approx(pan.angle(t - truth.delay))
            body = {
                n: v - truth.joint_zero.get(n, 0.0) for n, v in world.joint_angles("a", t).items()
            }
            expected = tree.camera_pose(body).matrix() @ truth.mounting()
            camera = world.truth(t, views=[]).robots["a"].camera
            assert np.allclose(camera.matrix(), expected, atol=1e-6)


@pytest.mark.parametrize(
    ("perturb", "key", "says"),
    [
        (
            "{ joint_zero = { head_nod = 0.1 } }",
            "robots[0].perturb.joint_zero.head_nod",
            "no movable joint",
        ),
        ("{ camera_offset = [0.5, 0.0, 0.0] }", "robots[0].perturb.camera_offset[0]", "-0.2"),
        ("{ delay = -0.1 }", "robots[0].perturb.delay", "0"),
    ],
)
def test_a_bad_perturbation_names_file_and_key(
    tmp_path: Path, perturb: str, key: str, says: str
) -> None:
    text = SCENE.read_text(encoding="utf-8")
    start = text.index("perturb = {")
    end = text.index("\n", start)
    text = text[:start] + f"perturb = {perturb}" + text[end:]
    text = text.replace('"../robots/myon.toml"', f'"{PROFILE}"')
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        open_world(path).close()
    assert str(err.value).startswith(f"{path}: {key}")
    assert says in str(err.value)


def test_calibrate_head_recovers_the_perturbation(lab: Path, capsys) -> None:
    profile = lab / "robots" / "myon.toml"
    before = profile.read_bytes()
    out = lab / "robots" / "myon-corrected.toml"
    scene = str(lab / "scenes" / "perturbed.toml")
    argv = ["--robot", str(profile), "--sim", scene, "--name", "a", "--out", str(out), "--json"]
    code, printed, err = _run(capsys, "calibrate-head", *argv, *SWEEP)
    assert code == 0, err
    lines = printed.strip().splitlines()
    assert len(lines) == 1
    result = json.loads(lines[0])
    for key in ("camera_offset", "camera_rotation", "joint_zero", "delay"):
        assert key in result
    assert result["reprojection_px_after"] < 1.0 < 10 < result["reprojection_px_before"]
    truth = load_scene(lab / "scenes" / "perturbed.toml")[0].robot("a").perturb
    assert abs(result["joint_zero"]["head_pan"] - truth.joint_zero["head_pan"]) < math.radians(0.2)
    assert abs(result["delay"] - truth.delay) < 0.005
    assert profile.read_bytes() == before
    corrected = load_profile(out)
    assert corrected.camera.joint_delay == pytest.approx(result["delay"], abs=1e-4)
    assert "calibrate-head:" in out.read_text(encoding="utf-8")
    # The corrected chain puts the camera where the perturbed robot's camera is.
    tree = KinematicTree.from_settings(corrected.kinematics)
    world = open_world(lab / "scenes" / "perturbed.toml")
    with world:
        for pan, tilt in ((0.1, -0.8), (0.6, -0.6)):
            world.follow("a", {"head_pan": pan, "head_tilt": tilt})
            camera = world.truth(0.0, views=[]).robots["a"].camera
            fk = tree.camera_pose({"head_pan": pan, "head_tilt": tilt})
            assert np.linalg.norm(fk.t - camera.t) < 0.005
            angle = math.acos(min(1.0, (np.trace(fk.R.T @ camera.R) - 1) / 2))
            assert math.degrees(angle) < 0.3
    # check-pose: the corrected profile finds the floor marker where it lies, the original not.
    for robot, within in ((out, True), (profile, False)):
        argv = ["--robot", str(robot), "--sim", scene, "--name", "a", "--json"]
        code, printed, err = _run(capsys, "check-pose", *argv, "--marker-at", "0.9", "-0.35")
        assert code == 0, err
        check = json.loads(printed)
        assert set(check) >= {"ground_error_m", "camera_position_error_m"}
        assert (check["ground_error_m"] < 0.02) == within


def test_an_unmeasured_world_is_refused_naming_the_pan_zero(lab: Path, capsys) -> None:
    code, _, err = _run(
        capsys, "calibrate-head", "--robot", str(lab / "robots" / "myon.toml"),
        "--sim", str(lab / "scenes" / "perturbed.toml"), "--out", str(lab / "x.toml"),
        "--unmeasured", *SWEEP,
    )  # fmt: skip
    assert code == 2
    assert "joint_zero.head_pan is undetermined" in err
    assert not (lab / "x.toml").exists()


def test_a_sweep_that_sees_no_markers_is_refused(lab: Path, capsys) -> None:
    code, _, err = _run(
        capsys, "calibrate-head", "--robot", str(lab / "robots" / "myon.toml"),
        "--sim", str(lab / "scenes" / "perturbed.toml"), "--out", str(lab / "y.toml"),
        "--pan", "-1.3", "-1.1", "--tilt", "0.3", "0.5", "--steps", "2", "2", "--fps", "5",
    )  # fmt: skip
    assert code == 2
    assert "too few markers" in err


def test_calibrate_head_from_a_recording(lab: Path, tmp_path: Path, capsys) -> None:
    """A sweep recorded as the daemon records it (JPEG frames, the joint readings at each
    frame's stamp), solved offline with the boxes' measured poses."""
    from percept.kinematics.gaze import Limits, sweep_grid, sweep_keyframes
    from percept.kinematics.pose import ground_pose, ground_transform, invert
    from percept.runtime.record.telemetry import Telemetry

    scene, platforms = load_scene(lab / "scenes" / "perturbed.toml")
    poses = sweep_grid(
        {"head_pan": Limits(0.0, 0.75), "head_tilt": Limits(-0.9, -0.5)}, steps=(3, 2)
    )
    keys = sweep_keyframes(poses, 0.5, 0.3)
    motion = {n: JointMotion(keyframes=tuple(k)) for n, k in keys.items()}
    a = dataclasses.replace(scene.robot("a"), joints=motion)
    scene = dataclasses.replace(scene, robots=(a, *scene.robots[1:]))
    path = tmp_path / "sweep.mcap"
    telemetry = Telemetry()
    telemetry.record(path, metadata={"robot": "a"})
    with SimWorld(scene, platforms) as world:
        for seq, t in enumerate(np.arange(0.0, max(k[-1][0] for k in keys.values()), 1 / 8)):
            joints = world.joint_readings("a", float(t))
            inputs = {"seq": seq, "t": float(t), "wall": 1.8e9 + t, "joints": joints}
            telemetry.log_frame(inputs, world.render("a", float(t)))
    telemetry.close()
    to_a = invert(ground_transform(*a.pose))
    boxes = []
    for b in scene.boxes:
        boxes += [
            "--box-at",
            str(b.id),
            *(f"{v:.6f}" for v in ground_pose(to_a @ ground_transform(*b.pose))),
        ]
    out = tmp_path / "corrected.toml"
    argv = ["--robot", str(lab / "robots" / "myon.toml"), "--from-recording", str(path)]
    code, printed, err = _run(capsys, "calibrate-head", *argv, *boxes, "--out", str(out), "--json")
    assert code == 0, err
    result = json.loads(printed)
    truth = a.perturb
    # 8 JPEG frames a second at 320x240, the readings only at the frames' stamps: looser than
    # a sweep with its own bus readings, still a tenth of the perturbation.
    assert abs(result["joint_zero"]["head_pan"] - truth.joint_zero["head_pan"]) < math.radians(0.3)
    assert abs(result["delay"] - truth.delay) < 0.005
    assert result["reprojection_px_after"] < 1.0
