"""The one ``percept`` package: what pyproject ships, what ``percept init`` copies, and a CLI that
starts without the heavy libraries."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

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


def test_help_imports_no_heavy_library() -> None:
    code = (
        "import sys\n"
        "from percept.runtime.cli import build_parser\n"
        "build_parser().format_help()\n"
        "heavy = {'numpy', 'cv2', 'mujoco', 'zenoh', 'scipy', 'foxglove'} & set(sys.modules)\n"
        "print(sorted(heavy))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, encoding="utf-8", check=True
    )
    assert out.stdout.strip() == "[]"


# A robot's install: the simulator and the test references are extras, not what the daemon needs.
ONBOARD_LEFT_OUT = ("mujoco", "filterpy", "matplotlib")


def test_a_plain_install_leaves_the_simulator_and_the_test_references_out() -> None:
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    core = " ".join(project["dependencies"])
    assert not [name for name in ONBOARD_LEFT_OUT if name in core]
    assert any(dep.startswith("mujoco") for dep in project["optional-dependencies"]["sim"])
    assert "percept[sim]" in project["optional-dependencies"]["test"]


# Runs percept in a child whose import system refuses MuJoCo, as on a robot's install.
WITHOUT_MUJOCO = (
    "import sys\n"
    "class NoMujoco:\n"
    "    def find_spec(self, name, path=None, target=None):\n"
    "        if name.partition('.')[0] == 'mujoco':\n"
    "            raise ModuleNotFoundError(f'No module named {name!r}', name=name)\n"
    "sys.meta_path.insert(0, NoMujoco())\n"
    "from percept.runtime.cli import main\n"
    "sys.exit(main(sys.argv[1:]))\n"
)


def test_a_command_that_needs_the_simulator_names_the_extra_without_it(tmp_path: Path) -> None:
    for argv in (
        ["demo", "--seconds", "5", "--out", str(tmp_path / "demo")],
        ["sim", "--scene", "tabletop-basic", "--robot", "a", "--out", str(tmp_path / "sim")],
        ["run", "--experiment", "tabletop", "--sim", "tabletop-basic"],
    ):
        done = subprocess.run(
            [sys.executable, "-c", WITHOUT_MUJOCO, *argv],
            capture_output=True,
            text=True,
            timeout=60,
            cwd=tmp_path,
        )
        assert done.returncode == 2, (argv, done.stderr[-2000:])
        assert "percept[sim]" in done.stderr, argv
        assert "Traceback" not in done.stderr, argv
    assert not (tmp_path / "demo").exists()
