"""A drawn scene end to end, as a lab runs it: ``percept scenarios`` writes it, ``percept sim``
renders it, ``percept track DIR --robot PROFILE`` tracks it with no other option (the number of
calibration frames comes with the folder), and so does ``percept track DIR`` alone: the folder
names the robot's shipped profile by a name that resolves."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from percept.runtime.cli import main

pytestmark = pytest.mark.timeout(300)

# The shipped room, kept short and simple: heads still (2 s of calibration), no arm, no people.
LAB = """
name = "lab"
[[robots]]
name = "a"
profile = "robotis-op3"
pose = [-0.72, 0.0, 0.0]
[objects]
count = [3, 3]
[heads]
still = 1.0
fixations = 0.0
sweep = 0.0
gaze = 0.0
[people]
p_walk = 0.0
p_stand = 0.0
p_calibration = 0.0
p_arm = 0.0
"""


def test_a_drawn_scene_renders_and_tracks_with_no_other_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lab = tmp_path / "lab.toml"
    lab.write_text(LAB, encoding="utf-8")
    scenes = tmp_path / "scenes"
    args = ["--count", "1", "--seed", "4", "--out", str(scenes), "--distribution", str(lab)]
    assert main(["scenarios", *args]) == 0
    scene = scenes / "lab-0004.toml"
    assert 'profile = "robotis-op3"' in scene.read_text(encoding="utf-8")
    seq = tmp_path / "seq"
    sim = ["sim", "--scene", str(scene), "--robot", "a", "--out", str(seq)]
    assert main([*sim, "--seconds", "4", "--fps", "10"]) == 0
    seqinfo = (seq / "seqinfo.ini").read_text(encoding="utf-8")
    assert "calibrationFrames=20" in seqinfo
    assert "profile=robotis-op3\n" in seqinfo  # the shipped name, not a path beside the scene
    capsys.readouterr()
    tracks = tmp_path / "tracks.txt"
    assert main(["track", str(seq), "--robot", "robotis-op3", "--out", str(tracks)]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["calibration_frames"] == 20  # 2 s at 10 fps, from seqinfo.ini
    assert summary["frames"] == 40 and summary["camera_poses"] == 40
    assert tracks.is_file()
    assert (seq / "gt" / "gt.txt").read_text(encoding="utf-8").strip()  # objects came
    alone = tmp_path / "alone.txt"
    assert main(["track", str(seq), "--out", str(alone)]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["camera_poses"] == 40
    assert alone.read_text(encoding="utf-8") == tracks.read_text(encoding="utf-8")


def test_a_bad_calibration_count_in_the_folder_names_the_file_and_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import cv2
    import numpy as np

    (tmp_path / "img1").mkdir()
    for k in (1, 2):
        cv2.imwrite(str(tmp_path / "img1" / f"{k:06d}.png"), np.zeros((8, 8, 3), np.uint8))
    (tmp_path / "seqinfo.ini").write_text(
        "[Sequence]\nframeRate=10\ncalibrationFrames=two\n", encoding="utf-8"
    )
    assert main(["track", str(tmp_path), "--out", str(tmp_path / "t.txt")]) == 2
    assert "seqinfo.ini: Sequence.calibrationFrames: expected a whole number" in (
        capsys.readouterr().err
    )
