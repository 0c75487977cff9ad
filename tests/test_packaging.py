"""The one ``percept`` package: what pyproject ships, what ``percept init`` copies, and a CLI that
starts without the heavy libraries."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from percept.config import KINDS, find, shipped, shipped_dir
from percept.config.loader import ConfigError
from percept.runtime.cli import main

REPO = Path(__file__).resolve().parents[1]
TOP = ("config", "drivers", "kinematics", "perception", "runtime")


def test_pyproject_names_every_package_folder() -> None:
    declared = set(
        tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"][
            "packages"
        ]
    )
    on_disk = {
        "percept." + ".".join(init.parent.relative_to(REPO).parts)
        for top in TOP
        for init in (REPO / top).rglob("__init__.py")
    }
    assert declared == on_disk


# What each package may import of percept besides itself (SPEC §2: imports point down only).
LAYERS = {
    "config": set(),
    "kinematics": {"config"},
    "drivers": {"config", "kinematics"},
    "perception": {"config", "kinematics"},
    "runtime": {"config", "kinematics", "drivers", "perception"},
}


def test_imports_point_down_only() -> None:
    found = re.compile(r"^\s*(?:from|import) percept\.(\w+)", re.M)
    wrong = [
        f"{path.relative_to(REPO)} imports percept.{used}"
        for top, allowed in LAYERS.items()
        for path in (REPO / top).rglob("*.py")
        for used in set(found.findall(path.read_text(encoding="utf-8")))
        if used != top and used not in allowed
    ]
    assert not wrong, wrong


def test_shipped_files_are_found_by_name_and_path(tmp_path: Path) -> None:
    assert {"myon", "robotis-op3", "sony-humanoid"} <= set(shipped("robots"))
    assert find("scenes", "tabletop-busy") == shipped_dir() / "scenes" / "tabletop-busy.toml"
    own = tmp_path / "mine.toml"
    own.write_text("", encoding="utf-8")
    assert find("scenes", own) == own
    try:
        find("experiments", "nowhere")
    except ConfigError as err:
        assert "shipped: tabletop" in str(err)
    else:
        raise AssertionError("a missing experiment was found")


def test_init_copies_the_shipped_files_and_keeps_a_users(tmp_path: Path, capsys) -> None:
    mine = tmp_path / "robots" / "myon.toml"
    mine.parent.mkdir()
    mine.write_text("# mine\n", encoding="utf-8")
    assert main(["init", str(tmp_path)]) == 0
    assert mine.read_text(encoding="utf-8") == "# mine\n"
    for kind in KINDS:
        assert {p.stem for p in (tmp_path / kind).glob("*.toml")} == set(shipped(kind))
    assert "kept" in capsys.readouterr().out
    # the copied experiment's relative profile paths point at the copied profiles
    assert main(["config", "--experiment", str(tmp_path / "experiments" / "tabletop.toml")]) == 0


def _imported(code: str, modules: set[str]) -> list[str]:
    """Which of ``modules`` a fresh interpreter has imported after running ``code``."""
    check = f"{code}\nimport json, sys\nprint(json.dumps(sorted({modules!r} & set(sys.modules))))\n"
    out = subprocess.run(
        [sys.executable, "-c", check], capture_output=True, encoding="utf-8", check=True
    )
    return list(json.loads(out.stdout))


def test_help_imports_no_heavy_library() -> None:
    code = "from percept.runtime.cli import build_parser\nbuild_parser().format_help()"
    assert _imported(code, {"numpy", "cv2", "mujoco", "zenoh", "scipy", "foxglove"}) == []


def test_the_daemons_modules_import_no_simulator_nor_test_library() -> None:
    # Each module imported is memory the daemon holds for its whole run: the simulated world,
    # the ROS 2 writer and the test references are imported only where a command uses them.
    code = (
        "import percept.runtime.commands.robot.run, percept.runtime.daemon.daemon\n"
        "import percept.runtime.daemon.devices, percept.runtime.daemon.pipeline\n"
        "import percept.perception.warm"
    )
    unused = {"mujoco", "matplotlib", "scipy", "filterpy", "rosbags", "pandas"}
    unused |= {"percept.drivers.sim.world", "percept.runtime.ros2.publisher"}
    assert _imported(code, unused) == []


# A robot's install: the simulator, the ROS 2 side, the AprilTag C library and the test
# references are extras, not what the daemon needs.
ONBOARD_LEFT_OUT = ("mujoco", "filterpy", "matplotlib", "scipy", "rosbags", "pupil-apriltags")
EXTRAS = {"sim": "mujoco", "ros2": "rosbags", "apriltag": "pupil-apriltags"}


def test_a_plain_install_leaves_the_optional_parts_and_the_test_references_out() -> None:
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    core = " ".join(project["dependencies"])
    assert not [name for name in ONBOARD_LEFT_OUT if name in core]
    extras = project["optional-dependencies"]
    for extra, dependency in EXTRAS.items():
        assert any(dep.startswith(dependency) for dep in extras[extra]), extra
    # The tests run every part: the test extra holds them all.
    assert f"percept[{','.join(EXTRAS)}]" in extras["test"]


def test_every_extra_a_feature_names_is_one_pyproject_declares() -> None:
    from percept.config.extras import EXTRAS as NAMED

    declared = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert {e.name for e in NAMED.values()} == set(EXTRAS)
    assert set(EXTRAS) <= set(declared["optional-dependencies"])


# Runs percept in a child where the top-level modules given in PERCEPT_REFUSE (comma-separated)
# are absent, as on a robot's install that leaves their extras out: None in sys.modules makes
# importlib.util.find_spec answer None and an import raise ModuleNotFoundError.
WITHOUT = (
    "import os, sys\n"
    "sys.modules.update(dict.fromkeys(os.environ['PERCEPT_REFUSE'].split(',')))\n"
    "from percept.runtime.cli import main\n"
    "sys.exit(main(sys.argv[1:]))\n"
)


def _without(module: str, argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", WITHOUT, *argv],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=cwd,
        env={**os.environ, "PERCEPT_REFUSE": module},
    )


def test_a_command_that_needs_the_simulator_names_the_extra_without_it(tmp_path: Path) -> None:
    for argv in (
        ["demo", "--seconds", "5", "--out", str(tmp_path / "demo")],
        ["sim", "--scene", "tabletop-basic", "--robot", "a", "--out", str(tmp_path / "sim")],
        ["run", "--experiment", "tabletop", "--sim", "tabletop-basic"],
    ):
        done = _without("mujoco", argv, tmp_path)
        assert done.returncode == 2, (argv, done.stderr[-2000:])
        assert "percept[sim]" in done.stderr, argv
        assert "Traceback" not in done.stderr, argv
    assert not (tmp_path / "demo").exists()


def test_the_ros2_export_names_its_extra_without_rosbags(tmp_path: Path) -> None:
    recording = tmp_path / "run.mcap"
    recording.write_bytes(b"")  # not read: the missing library is found first
    argv = ["export", "--ros2", str(recording), str(tmp_path / "bag")]
    done = _without("rosbags", argv, tmp_path)
    assert done.returncode == 2, done.stderr[-2000:]
    assert "pip install 'percept[ros2]'" in done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "bag").exists()


def test_a_config_that_enables_an_optional_part_without_it_names_file_key_and_extra(
    tmp_path: Path,
) -> None:
    # The shipped experiment, the files it names found where they are shipped.
    shipped_experiment = (
        find("experiments", "tabletop")
        .read_text(encoding="utf-8")
        .replace('"../', f'"{shipped_dir()}/')
    )
    # The module left out: the line of the experiment changed to need it, the key named.
    cases = {
        "rosbags": (
            "[landmarks]\n",
            '[ros2]\nenabled = true\nrouter = "tcp/127.0.0.1:7450"\n\n[landmarks]\n',
            "ros2.enabled",
            "percept[ros2]",
        ),
        "pupil_apriltags": (
            "follow = 2\n",
            'follow = 0\ndetector = "apriltag"\n',
            "landmarks.detector",
            "percept[apriltag]",
        ),
    }
    for module, (line, needing, key, extra) in cases.items():
        assert line in shipped_experiment
        path = tmp_path / f"{module}.toml"
        path.write_text(shipped_experiment.replace(line, needing), encoding="utf-8")
        done = _without(module, ["config", "--experiment", str(path)], tmp_path)
        assert done.returncode == 2, (module, done.stderr[-2000:])
        assert f"{path.name}: {key}" in done.stderr, done.stderr
        assert f"pip install '{extra}'" in done.stderr, done.stderr
        # With the library there, the same file loads.
        assert main(["config", "--experiment", str(path)]) == 0


def test_install_size_charges_every_file_to_its_distribution(tmp_path: Path) -> None:
    """bench/install_size.py on a small venv: a package's recorded files and its unrecorded
    __pycache__ go to its distribution, a stray file to nobody, and all add up to the venv."""
    import json

    site = tmp_path / "lib" / "python3.11" / "site-packages"
    (site / "pkg" / "__pycache__").mkdir(parents=True)
    (site / "pkg-1.0.dist-info").mkdir()
    kib = 1024
    (site / "pkg" / "__init__.py").write_bytes(b"#" * 256 * kib)
    (site / "pkg" / "__pycache__" / "__init__.cpython-311.pyc").write_bytes(b"\0" * 512 * kib)
    (site / "pkg-1.0.dist-info" / "METADATA").write_text("Name: pkg\nVersion: 1.0\n")
    (site / "pkg-1.0.dist-info" / "RECORD").write_text(
        "pkg/__init__.py,,\npkg-1.0.dist-info/METADATA,,\npkg-1.0.dist-info/RECORD,,\n"
    )
    (site / "stray.bin").write_bytes(b"\0" * 1024 * kib)
    done = subprocess.run(
        [sys.executable, str(REPO / "bench" / "install_size.py"), str(tmp_path), "--json"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    mb = json.loads(done.stdout)
    assert set(mb) == {"pkg", "(not a distribution)", "total"}
    assert 0.75 <= mb["pkg"] < 0.9  # 768 KiB of files and its folders' blocks
    assert 1.0 <= mb["(not a distribution)"] < 1.1
    assert mb["total"] == pytest.approx(mb["pkg"] + mb["(not a distribution)"], abs=0.1)
