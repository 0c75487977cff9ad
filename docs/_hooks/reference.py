"""The documentation site's generated parts: the CLI reference from the ``percept`` argparse
parsers and the configuration reference from the settings' dataclasses, written when the site is
built so that they cannot drift from the code.

MkDocs runs this file as a hook (``hooks:`` in mkdocs.yml): a page line that is exactly
``<!-- generated: NAME -->`` is replaced by the Markdown of ``GENERATORS[NAME]``.
tests/test_docs.py calls the same functions without MkDocs installed.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable, Iterator

from percept.config.loader import fields_doc
from percept.drivers.sim.scene import Scene
from percept.runtime.cli import build_parser
from percept.runtime.net.router import RouterSettings
from percept.runtime.settings.experiment import Experiment
from percept.runtime.settings.profile import PlatformProfile

MARKER = re.compile(r"^<!-- generated: ([a-z-]+) -->$", re.M)
#: A Sphinx cross-reference role of a docstring (``:class:`~percept.x.Y```) as Markdown renders it.
ROLE = re.compile(r":(?:attr|class|func|meth|data|mod|exc|obj):<code>~?")

#: The kinds of configuration file, their dataclass and the shipped folder they live in.
CONFIG_KINDS: tuple[tuple[str, type, str], ...] = (
    ("Robot profile", PlatformProfile, "robots/NAME.toml"),
    ("Experiment", Experiment, "experiments/NAME.toml"),
    ("Scene of the simulated world", Scene, "scenes/NAME.toml"),
    ("Lab router", RouterSettings, "lab/router.toml"),
)


def _cell(text: str) -> str:
    """``text`` safe inside one Markdown table cell."""
    return text.replace("|", "\\|").replace("\n", " ").strip()


def subcommands(
    parser: argparse.ArgumentParser, prog: str = "percept"
) -> Iterator[tuple[str, argparse.ArgumentParser, str]]:
    """(full command, its parser, its one-line help) of every subcommand under ``parser``, depth
    first, nested subcommands (``percept eval foreground``) included."""
    for action in parser._actions:
        if not isinstance(action, argparse._SubParsersAction):
            continue
        helps = {a.dest: a.help or "" for a in action._choices_actions}
        for name, sub in action.choices.items():
            command = f"{prog} {name}"
            yield command, sub, helps.get(name, "")
            yield from subcommands(sub, command)


def options(parser: argparse.ArgumentParser) -> Iterator[tuple[str, str, str]]:
    """(its option strings or argument name in backticks, its value's name, its help with
    defaults filled in) of each option of ``parser``,
    --help and subcommand choices left out."""
    formatter = parser._get_formatter()
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
            continue
        if action.help == argparse.SUPPRESS:
            continue
        name = ", ".join(f"`{o}`" for o in action.option_strings) or f"`{action.dest}`"
        if action.nargs == 0:
            value = ""
        elif action.choices is not None:
            value = "{" + ",".join(str(c) for c in action.choices) + "}"
        elif isinstance(action.metavar, tuple):
            value = " ".join(action.metavar)
        else:
            value = str(action.metavar or (action.dest.upper() if action.option_strings else ""))
        text = formatter._expand_help(action) if action.help else ""
        if action.default not in (None, False, [], argparse.SUPPRESS) and "default" not in text:
            text = f"{text} (default {action.default})".strip()
        yield name, value, text


def cli_reference() -> str:
    """Every ``percept`` command: its usage and a table of its options."""
    parts: list[str] = []
    for command, parser, help_ in subcommands(build_parser()):
        level = "#" * (command.count(" ") + 1)
        usage = parser.format_usage().removeprefix("usage: ").strip()
        parts += [f"{level} {command}", "", help_[:1].upper() + help_[1:] + ".", ""]
        parts += ["```", usage, "```", ""]
        rows = [
            f"| {name} | {f'`{_cell(value)}`' if value else ''} | {_cell(text)} |"
            for name, value, text in options(parser)
        ]
        if rows:
            parts += ["| option | value | what it does |", "|---|---|---|", *rows, ""]
    return "\n".join(parts)


def config_reference() -> str:
    """Every key of every kind of configuration file: type, default and meaning."""
    parts: list[str] = []
    for title, cls, where in CONFIG_KINDS:
        shipped = f"Shipped files: `{where}` (copied by `percept init DIR`)."
        parts += [f"## {title}", "", shipped, ""]
        parts += ["| key | type | default | meaning |", "|---|---|---|---|"]
        parts += [
            f"| `{key}` | {_cell(kind)} | `{_cell(default)}` | {_cell(doc)} |"
            for key, kind, default, doc in fields_doc(cls)
        ]
        parts.append("")
    return "\n".join(parts)


GENERATORS: dict[str, Callable[[], str]] = {
    "cli": cli_reference,
    "config": config_reference,
}


def expand(markdown: str) -> str:
    """``markdown`` with each generated-part marker replaced by that part."""
    return MARKER.sub(lambda m: GENERATORS[m.group(1)](), markdown)


def on_page_markdown(markdown: str, **_: object) -> str:
    """MkDocs hook: fill in the generated parts of a page."""
    return expand(markdown)


def on_page_content(html: str, **_: object) -> str:
    """MkDocs hook: the API pages' docstrings show a role's target as code, without the role."""
    return ROLE.sub("<code>", html)
