"""The documentation: the generated references name every command, option and configuration key;
every key of summary.json and of each message is explained; the README stays a front door; no
page says what only the developers know (issue numbers, the design card, dates of work); the
site's navigation and links point at pages that exist. Runs without MkDocs installed: the site
itself is built by .ci/run (``mkdocs build --strict``)."""

from __future__ import annotations

import importlib.util
import re
import typing
from dataclasses import fields, is_dataclass
from pathlib import Path
from types import ModuleType

import pytest

from percept.config.loader import fields_doc
from percept.runtime.cli import build_parser
from percept.runtime.net import messages
from percept.runtime.net.codec import Key
from percept.runtime.record.summary import FeatureDifference, RobotSummary, Summary

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
README = REPO / "README.md"


def _hook() -> ModuleType:
    """docs/_hooks/reference.py, the MkDocs hook that writes the generated references."""
    spec = importlib.util.spec_from_file_location("docs_reference", DOCS / "_hooks/reference.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


REFERENCE = _hook()


def _pages() -> list[Path]:
    return sorted(DOCS.rglob("*.md"))


def _text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def test_cli_reference_names_every_command_and_option() -> None:
    page = REFERENCE.expand(_text(DOCS / "reference/cli.md"))
    commands = list(REFERENCE.subcommands(build_parser()))
    assert len(commands) > 20
    missing = []
    for command, parser, _ in commands:
        if not re.search(rf"^#+ {re.escape(command)}$", page, re.M):
            missing.append(command)
        section = page.split(f" {command}\n", 1)[1]
        missing += [
            f"{command} {option}"
            for action in parser._actions
            for option in action.option_strings
            if option not in ("-h", "--help") and f"`{option}" not in section.split("\n#", 1)[0]
        ]
    assert not missing, missing


def test_configuration_reference_names_every_key() -> None:
    page = REFERENCE.expand(_text(DOCS / "reference/configuration.md"))
    kinds = REFERENCE.CONFIG_KINDS
    assert {cls.__name__ for _, cls, _ in kinds} >= {"PlatformProfile", "Experiment", "Scene"}
    missing = [
        f"{cls.__name__}: {key}"
        for _, cls, _ in kinds
        for key, *_ in fields_doc(cls)
        if f"| `{key}` |" not in page
    ]
    assert not missing, missing
    assert "<!-- generated" not in page


def test_a_missing_option_would_fail() -> None:
    """The check above reads the parser, not the page: an option the page lacks is found."""
    page = REFERENCE.cli_reference()
    assert "`--once`" in page
    assert "`--no-such-option`" not in page


def _keys(typed_dict: type) -> set[str]:
    return set(typing.get_type_hints(typed_dict))


def test_every_summary_key_is_explained() -> None:
    page = _text(DOCS / "output-files.md")
    keys = _keys(Summary) | _keys(RobotSummary) | _keys(FeatureDifference)
    assert len(keys) > 25
    missing = sorted(k for k in keys if f"| `{k}` |" not in page)
    assert not missing, missing


def _json_keys(cls: type) -> set[str]:
    """A message class's keys in JSON (a field's ``Key`` where it is not the field's name)."""
    hints = typing.get_type_hints(cls, include_extras=True)
    keys = set()
    for f in fields(cls):
        renamed = [m.name for m in getattr(hints[f.name], "__metadata__", ()) if isinstance(m, Key)]
        keys.add(renamed[0] if renamed else f.name)
    return keys


def _section(page: str, schema: str) -> str:
    head = f"## `{schema}`\n"
    assert head in page, f"no section for {schema}"
    return page.split(head, 1)[1].split("\n## ", 1)[0]


def test_every_message_key_is_explained() -> None:
    page = _text(DOCS / "reference/messages.md")
    classes = [getattr(messages, n) for n in dir(messages)]
    schemas = {
        c: c.SCHEMA
        for c in classes
        if isinstance(c, type) and is_dataclass(c) and isinstance(getattr(c, "SCHEMA", None), str)
    }
    # The older schemas a receiver still reads are named on the page of their successor.
    assert set(schemas.values()) == set(messages.SCHEMAS) - set(messages.OLDER)
    assert all(f"`{old}`" in page for old in messages.OLDER)
    nested = {
        messages.World: [messages.WorldObject, messages.PeerPose],
        messages.Boxes: [],
    }
    missing = []
    for cls, schema in schemas.items():
        section = _section(page, schema)
        keys = {"schema"} | _json_keys(cls)
        for inner in nested.get(cls, []):
            keys |= _json_keys(inner)
        if cls in (messages.World, messages.Boxes):
            keys |= {"id", "x", "y", "theta", "n"}  # a box
        if cls is messages.World:
            keys |= set(typing.get_type_hints(messages.Camera))
        missing += [f"{schema}: {k}" for k in sorted(keys) if f"`{k}`" not in section]
    assert not missing, missing


USER_TEXT = [README, *sorted(DOCS.rglob("*.md"))]


@pytest.mark.parametrize("path", USER_TEXT, ids=lambda p: str(p.relative_to(REPO)))
def test_no_issue_numbers_design_card_or_workspace_paths(path: Path) -> None:
    text = _text(path)
    found = re.findall(r"\bissues? #?\d+|\bSPEC\b|§|shared/data", text, re.I)
    assert not found, found


@pytest.mark.parametrize(
    "path",
    [p for p in USER_TEXT if p.name != "benchmarks.md"],
    ids=lambda p: str(p.relative_to(REPO)),
)
def test_no_dated_notes_outside_the_benchmarks(path: Path) -> None:
    assert not re.findall(r"\b20\d\d-\d\d-\d\d\b", _text(path))


def _quick_start(readme: str) -> list[str]:
    block = readme.split("## Quick start", 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    return [line for line in block.splitlines() if line.strip()]


def test_readme_is_a_front_door() -> None:
    readme = _text(README)
    assert len(readme.splitlines()) <= 300
    assert _quick_start(readme) == [
        "python3 -m venv .venv && .venv/bin/pip install -q '.[sim]' && .venv/bin/percept demo",
        "python3 -m venv .venv && .venv/bin/pip install -q '.[test]' && .venv/bin/ruff check . "
        "&& .venv/bin/mypy && .venv/bin/python -m pytest",
    ]
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", readme)
    assert images, "the README shows the demo's figure"
    for image in images:
        assert (REPO / image).is_file(), image
        assert (REPO / image).stat().st_size < 300_000, image
    assert (REPO / "LICENSE").read_text(encoding="utf-8").lstrip().startswith("Apache License")


def _links(path: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", _text(path), flags=re.S)
    return [
        link.split("#", 1)[0]
        for link in re.findall(r"\]\(([^)\s]+)\)", text)
        if not re.match(r"[a-z]+:", link) and not link.startswith("#")
    ]


@pytest.mark.parametrize("path", USER_TEXT, ids=lambda p: str(p.relative_to(REPO)))
def test_relative_links_point_at_files(path: Path) -> None:
    broken = [link for link in _links(path) if not (path.parent / link).exists()]
    assert not broken, broken


def test_navigation_holds_every_page_and_only_pages_that_exist() -> None:
    config = _text(REPO / "mkdocs.yml")
    nav = re.findall(r"^\s*-\s+(?:[^:\n]+:\s+)?([\w/.-]+\.md)\s*$", config, re.M)
    assert len(nav) > 15
    assert [p for p in nav if not (DOCS / p).is_file()] == []
    pages = {str(p.relative_to(DOCS)) for p in _pages()}
    assert pages - set(nav) == set()
    for page in ("getting-started.md", "bring-up.md", "output-files.md", "reference/api.md"):
        assert page in nav
