"""Kinematic trees and forward kinematics, checked against an independent URDF library."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from percept.config.loader import ConfigError
from percept.kinematics.frame_pose import FramePoses, pose_for_frame
from percept.kinematics.pose import CameraPose, rpy_matrix, transform
from percept.kinematics.settings import JointSpec, KinematicsSettings
from percept.kinematics.tree import KinematicsError, KinematicTree, read_urdf
from percept.runtime.cli import main
from percept.runtime.settings.profile import load_profile

REPO = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
OP3_DIR = DATA / "robots" / "robotis-op3"
OP3_URDF = OP3_DIR / "robotis_op3.urdf"
PROFILES = REPO / "config" / "robots"

needs_data = pytest.mark.skipif(not OP3_URDF.is_file(), reason=f"{DATA} (public data) is absent")


def _op3_urdf_settings(**extra) -> KinematicsSettings:
    return KinematicsSettings(
        camera_link="cam_gazebo_link", root_link="body_link", urdf=OP3_URDF, **extra
    )


@pytest.fixture(scope="module")
def yourdf():
    yourdfpy = pytest.importorskip("yourdfpy")
    return yourdfpy.URDF.load(str(OP3_URDF), load_meshes=False, build_scene_graph=True)


@needs_data
def test_urdf_fk_matches_yourdfpy_at_random_configurations(yourdf) -> None:
    tree = KinematicTree.from_settings(_op3_urdf_settings())
    assert len(tree.movable_joints) == 20
    assert set(tree.movable_joints) == set(yourdf.actuated_joint_names)
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(60):
        q = {name: rng.uniform(-2.8, 2.8) for name in tree.movable_joints}
        yourdf.update_cfg(q)
        for link in tree.links:
            # yourdfpy: get_transform(frame_to, frame_from) is frame_from <- frame_to.
            theirs = yourdf.get_transform(link, "body_link")
            ours = tree.link_transform(link, q)
            worst = max(worst, float(np.abs(theirs - ours).max()))
    assert worst < 1e-9


@needs_data
def test_tree_order_is_topological() -> None:
    tree = KinematicTree.from_settings(_op3_urdf_settings())
    seen = {"body_link"}
    for joint in tree.joints:
        assert joint.parent in seen, joint.name
        seen.add(joint.child)
    # Joints above the root (world -> base -> body_link) are not part of this tree.
    assert "base_fixed" not in [j.name for j in tree.joints]


@needs_data
def test_op3_profile_chain_matches_the_urdf_standing_on_its_soles() -> None:
    trimesh = pytest.importorskip("trimesh")
    # The sole is the foot mesh's lowest point; its middle is the mesh's x/y centre.
    foot = trimesh.load(str(OP3_DIR / "meshes" / "ll6.stl")).bounds * 0.001
    sole_offset = ((foot[0, 0] + foot[1, 0]) / 2, 0.0, foot[0, 2])
    full = KinematicTree.from_settings(
        _op3_urdf_settings(
            sole_links=("l_ank_roll_link", "r_ank_roll_link"), sole_offset=sole_offset
        )
    )
    inline = KinematicTree.from_settings(load_profile(PROFILES / "robotis-op3.toml").kinematics)
    rng = np.random.default_rng(6)
    for _ in range(30):
        q = {"head_pan": rng.uniform(-1.5, 1.5), "head_tilt": rng.uniform(-1.2, 0.6)}
        a, b = full.camera_pose(q), inline.camera_pose(q)
        assert np.abs(a.R - b.R).max() < 1e-9
        assert np.abs(a.t - b.t).max() < 1e-9


@needs_data
def test_ground_frame_follows_the_feet(yourdf) -> None:
    soles = ("l_ank_roll_link", "r_ank_roll_link")
    tree = KinematicTree.from_settings(
        _op3_urdf_settings(sole_links=soles, sole_offset=(0.024, 0.0, -0.0305))
    )
    straight = tree.camera_pose({}).t[2]
    # A squat: hips and ankles pitch to keep the feet flat while the knees bend.
    squat = {}
    for side, sign in (("l", 1), ("r", -1)):
        squat |= {f"{side}_hip_pitch": -0.6 * sign, f"{side}_knee": 1.2 * sign}
        squat |= {f"{side}_ank_pitch": 0.6 * sign}
    yourdf.update_cfg({name: squat.get(name, 0.0) for name in yourdf.actuated_joint_names})
    for link in soles:
        sole = tree.link_transform(link, squat)
        assert np.allclose(sole[:3, :3], np.eye(3), atol=1e-9)
        assert sole[2, 3] == pytest.approx(0.0305, abs=1e-9)
    # Independently: the camera's height above the (flat) soles from yourdfpy's transforms.
    cam = yourdf.get_transform("cam_gazebo_link", "body_link")
    foot = yourdf.get_transform("l_ank_roll_link", "body_link")
    expected = cam[2, 3] - foot[2, 3] + 0.0305
    assert tree.camera_pose(squat).t[2] == pytest.approx(expected, abs=1e-9)
    assert tree.camera_pose(squat).t[2] < straight - 0.02


def test_inline_joint_overrides_the_urdf(tmp_path: Path) -> None:
    urdf = tmp_path / "r.urdf"
    urdf.write_text(
        '<robot name="r"><link name="base"/><link name="head"/><link name="cam"/>'
        '<joint name="pan" type="revolute"><parent link="base"/><child link="head"/>'
        '<origin xyz="0 0 0.5"/><axis xyz="0 0 1"/></joint>'
        '<joint name="mount" type="fixed"><parent link="head"/><child link="cam"/>'
        '<origin xyz="0.1 0 0"/></joint></robot>',
        encoding="utf-8",
    )
    joints, links = read_urdf(urdf)
    assert [j.name for j in joints] == ["pan", "mount"] and links == {"base", "head", "cam"}
    moved = JointSpec(name="mount", parent="head", child="cam", type="fixed", xyz=(0.2, 0, 0.1))
    tree = KinematicTree.from_settings(
        KinematicsSettings(camera_link="cam", root_link="base", urdf=urdf, joints=(moved,))
    )
    pose = tree.camera_pose({"pan": math.pi / 2})
    assert np.allclose(pose.t, [0.0, 0.2, 0.6])
    # A URDF joint without <axis> turns about x (the URDF default).
    text = urdf.read_text(encoding="utf-8").replace('<axis xyz="0 0 1"/>', "")
    urdf.write_text(text, encoding="utf-8")
    assert read_urdf(urdf)[0][0].axis == (1.0, 0.0, 0.0)


def _chain(*joints: tuple[str, str, str]) -> tuple[JointSpec, ...]:
    return tuple(JointSpec(name=n, parent=p, child=c, xyz=(0, 0, 0.1)) for n, p, c in joints)


@pytest.mark.parametrize(
    ("joints", "camera", "message"),
    [
        (
            _chain(("a", "torso", "neck"), ("b", "nekc", "head")),
            "head",
            "joint 'b': parent link 'nekc' is unknown",
        ),
        (
            _chain(("a", "torso", "neck"), ("b", "head", "eye"), ("c", "eye", "head")),
            "neck",
            "form a cycle",
        ),
        (
            _chain(("a", "torso", "neck"), ("b", "neck", "torso")),
            "neck",
            "makes the root link 'torso' its own descendant",
        ),
        (_chain(("a", "torso", "neck"), ("a", "neck", "head")), "head", "'a' is defined twice"),
        (
            _chain(("a", "torso", "neck"), ("b", "torso", "neck")),
            "neck",
            "link 'neck' has two parent joints, 'a' and 'b'",
        ),
        (_chain(("a", "torso", "neck")), "camera", "camera_link 'camera' is not a link"),
    ],
)
def test_bad_trees_are_refused_naming_the_joint_or_link(joints, camera, message) -> None:
    with pytest.raises(KinematicsError, match=message):
        KinematicsSettings(camera_link=camera, root_link="torso", joints=joints)


def test_bad_profile_is_refused_with_file_and_key(tmp_path: Path) -> None:
    text = (PROFILES / "robotis-op3.toml").read_text(encoding="utf-8")
    bad = tmp_path / "op3.toml"
    bad.write_text(
        text.replace('parent = "head_pan_link"', 'parent = "head_pan_lnk"'), encoding="utf-8"
    )
    with pytest.raises(ConfigError) as info:
        load_profile(bad)
    assert str(info.value).startswith(f"{bad}: kinematics: joint 'head_tilt': parent link")
    bad.write_text(text.replace('name = "head_pan"', 'name = "head_yaw"', 1), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_profile(bad)
    assert str(info.value).startswith(
        f"{bad}: joints[0].name: joint 'head_yaw' is not in the kinematic chain"
    )


@pytest.mark.parametrize("profile", sorted(PROFILES.glob("*.toml")))
def test_every_shipped_profile_points_its_camera_forward_and_up_high(profile: Path) -> None:
    p = load_profile(profile)
    tree = KinematicTree.from_settings(p.kinematics)
    pose = tree.camera_pose({})
    assert np.allclose(pose.R @ pose.R.T, np.eye(3), atol=1e-12)
    assert pose.R[0, 0] > 0.99  # optical axis along the robot's x at zero angles
    assert 0.2 < pose.t[2] < 1.5
    # The conventions of README "Porting": tilting down lowers the optical axis, panning left
    # turns it to +y.
    if "head_tilt" in tree.camera_joints:
        assert tree.camera_pose({"head_tilt": -0.5}).R[2, 0] < -0.4
    if "head_pan" in tree.camera_joints:
        assert tree.camera_pose({"head_pan": 0.5}).R[1, 0] > 0.4


def test_strict_needs_every_camera_joint() -> None:
    tree = KinematicTree.from_settings(load_profile(PROFILES / "myon.toml").kinematics)
    with pytest.raises(KinematicsError, match="head_tilt"):
        tree.camera_pose({"head_pan": 0.1}, strict=True)


def test_rpy_is_urdf_fixed_axis_order() -> None:
    roll, pitch, yaw = 0.3, -0.7, 1.1

    def rot(axis: int, a: float) -> np.ndarray:
        c, s = math.cos(a), math.sin(a)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        R = np.eye(3)
        R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
        return R

    expected = rot(2, yaw) @ rot(1, pitch) @ rot(0, roll)
    assert np.allclose(rpy_matrix((roll, pitch, yaw)), expected, atol=1e-15)
    assert np.allclose(transform((1, 2, 3), (roll, pitch, yaw))[:3, 3], [1, 2, 3])


def test_frame_pose_marks_old_or_stale_joint_readings() -> None:
    tree = KinematicTree.from_settings(load_profile(PROFILES / "robotis-op3.toml").kinematics)

    class Sample:
        def __init__(self, angles, age, stale=frozenset()):
            self.angles, self.t, self.age, self.stale = angles, 10.0, age, stale

    good = pose_for_frame(tree, Sample({"head_pan": 0.1, "head_tilt": -0.3}, 0.01), 0.05)
    assert good.fresh and good.problems == ()
    assert np.allclose(good.pose.R, tree.camera_pose({"head_pan": 0.1, "head_tilt": -0.3}).R)
    old = pose_for_frame(tree, Sample({"head_pan": 0.1, "head_tilt": -0.3}, 0.2), 0.05)
    assert not old.fresh and "200 ms old" in old.problems[0]
    stale = pose_for_frame(tree, Sample({"head_pan": 0.1}, 0.0, frozenset({"head_pan"})), 0.05)
    assert not stale.fresh and len(stale.problems) == 2


def test_frame_poses_share_one_pose_while_the_angles_stay_and_compute_a_new_one_after() -> None:
    tree = KinematicTree.from_settings(load_profile(PROFILES / "robotis-op3.toml").kinematics)

    class Sample:
        def __init__(self, angles, age):
            self.angles, self.t, self.age, self.stale = angles, 10.0, age, frozenset()

    poses = FramePoses(tree, 0.05)
    first = poses(Sample({"head_pan": 0.1, "head_tilt": -0.3}, 0.01))
    again = poses(Sample({"head_pan": 0.1, "head_tilt": -0.3}, 0.2))
    assert again.pose is first.pose and first.fresh and not again.fresh  # freshness per frame
    turned = poses(Sample({"head_pan": 0.1 + 1e-12, "head_tilt": -0.3}, 0.01))
    assert turned.pose is not first.pose and not np.array_equal(turned.pose.R, first.pose.R)
    expected = tree.camera_pose({"head_pan": 0.1 + 1e-12, "head_tilt": -0.3})
    assert np.array_equal(turned.pose.R, expected.R) and np.array_equal(turned.pose.t, expected.t)


def test_fk_command_json(capsys: pytest.CaptureFixture[str]) -> None:
    profile = PROFILES / "robotis-op3.toml"
    assert main(["fk", "--robot", str(profile), "--set", "head_tilt=-0.4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == {"R", "t", "frame"} and out["frame"] == "ground"
    tree = KinematicTree.from_settings(load_profile(profile).kinematics)
    expected = tree.camera_pose({"head_tilt": -0.4})
    assert np.allclose(out["R"], expected.R) and np.allclose(out["t"], expected.t)
    assert CameraPose.from_dict(out).t[2] == pytest.approx(expected.t[2])
    # At zero angles the OP3 camera is 0.21475 m above body_link, 0.27915 m above the soles.
    assert main(["fk", "--robot", str(profile), "--json"]) == 0
    zero = json.loads(capsys.readouterr().out)
    assert zero["t"] == pytest.approx([0.02325, 0.0, 0.4939], abs=1e-9)


def test_fk_command_refuses_unknown_joint(capsys: pytest.CaptureFixture[str]) -> None:
    profile = PROFILES / "sony-humanoid.toml"
    assert main(["fk", "--robot", str(profile), "--set", "neck=1"]) == 2
    assert "unknown joint 'neck'" in capsys.readouterr().err


def test_prismatic_and_continuous_joints() -> None:
    joints = (
        JointSpec(name="lift", parent="base", child="mast", type="prismatic", axis=(0, 0, 1)),
        JointSpec(name="spin", parent="mast", child="cam", type="continuous", xyz=(0.1, 0, 0.5)),
    )
    tree = KinematicTree.from_settings(
        KinematicsSettings(camera_link="cam", root_link="base", joints=joints)
    )
    pose = tree.camera_pose({"lift": 0.25, "spin": 4 * math.pi})
    assert np.allclose(pose.t, [0.1, 0.0, 0.75]) and np.allclose(pose.R, np.eye(3))


@needs_data
def test_optical_camera_link_with_camera_rpy() -> None:
    # cam_link is the z-forward optical frame; camera_rpy turns it into the chapter's frame.
    optical = KinematicTree.from_settings(
        KinematicsSettings(
            camera_link="cam_link",
            root_link="body_link",
            urdf=OP3_URDF,
            camera_rpy=(math.pi / 2, -math.pi / 2, 0.0),
        )
    )
    forward = KinematicTree.from_settings(_op3_urdf_settings())
    q = {"head_pan": 0.4, "head_tilt": -0.7}
    assert np.allclose(optical.camera_pose(q).R, forward.camera_pose(q).R, atol=1e-12)
    assert np.allclose(optical.camera_pose(q).t, forward.camera_pose(q).t, atol=1e-12)
