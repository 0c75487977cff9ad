"""``percept demo`` end to end: two simulated robots (their own ``percept run`` each, servos
through the emulator), the joint-attention monitor and the pointing and guessing games; the
summary scored against the simulated truth, and the figure."""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import time

import pytest

from tests.support.daemon import ROOT, endpoint, experiment_copy

SECONDS = 15  # scene time 0 comes 3 s after the start, the objects are down 4 s later: 8 s of games


@pytest.mark.timeout(120)
def test_demo_scores_two_robots_and_draws_the_figure(tmp_path):
    import cv2

    out = tmp_path / "demo"
    out.mkdir()
    earlier = b"an earlier run's recording of robot a, kept"
    (out / "a.mcap").write_bytes(earlier)
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    cmd = [sys.executable, "-m", "percept.runtime.cli", "demo", "--seconds", str(SECONDS)]
    experiment = experiment_copy(tmp_path)
    cmd += ["--out", str(out), "--experiment", str(experiment)]
    began = time.monotonic()
    # Another daemon holds the experiment's port of robot a: the demo runs on ports of its own.
    with socket.socket() as held:
        port = int(endpoint(experiment, "a").rsplit(":", 1)[1])
        held.bind(("127.0.0.1", port))
        held.listen()
        done = subprocess.run(
            cmd, cwd=ROOT, env=env, capture_output=True, encoding="utf-8", timeout=100
        )
    took = time.monotonic() - began
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    assert took < SECONDS + 15  # the bound for the demo's end
    # A progress line about every second: time, and each robot's frame rate and anchors.
    progress = re.findall(rf"^\s*[\d.]+/{SECONDS} s \| a: .* \| b: ", done.stdout, re.M)
    assert len(progress) >= SECONDS // 2, done.stdout
    assert "objects matched at end" in done.stdout  # the table
    assert "false anchors (mean / over 10 s)" in done.stdout
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["exit_codes"] == {"a": 0, "b": 0}
    assert summary["scene"] == "tabletop-basic"  # the shipped name, not a path into the venv
    for robot in ("a", "b"):
        r = summary["robots"][robot]
        assert r["true_objects_end"] == 5
        assert r["matched_end"] >= 4, r
        # precision against the truth: the five objects tracked, few anchors on nothing
        assert r["mota"] > 0.6 and r["idf1"] > 0.6, r
        assert r["false_anchors_mean"] < 1.0, r
        assert r["ground_error_m_median"] < 0.03, r
        assert r["peer_position_error_m_median"] < 0.03, r
        assert r["peer_heading_error_rad_median"] < 0.05, r
        assert r["pointing_success"] >= 1, r
        # a few rounds only: the first ones make categories, words may come later
        assert r["guessing_games"] >= r["guessing_as_speaker"] >= 1 and r["categories"] >= 1, r
        assert r["fps_mean"] > 5, r
        # the daemon's CPU by thread, its perception thread's share within the whole's
        threads = r["cpu_cores_by_thread"]
        assert 0 < threads["perception"] <= r["cpu_cores_mean"] + 0.02, r
    difference = summary["scaled_feature_difference"]
    assert difference["objects_seen_by_both"] >= 4
    assert difference["mean_shared_features"] < 0.2
    assert summary["joint_attention_events"] >= 1
    assert summary["guessing_games_per_minute"] > 0
    figure = cv2.imread(str(out / "figure.png"))
    assert figure is not None and figure.shape[0] > 600 and figure.shape[1] > 600
    # a's recording went to the next free name, and was the one scored
    assert (out / "a.mcap").read_bytes() == earlier
    for name in ("a.1.mcap", "b.mcap"):
        assert (out / name).stat().st_size > 0
