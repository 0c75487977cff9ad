"""The ``percept`` command line.

Each subcommand is one module in :mod:`percept.runtime.commands` with four names:

- ``NAME``: the subcommand's name (``percept NAME``),
- ``HELP``: a one-line description,
- ``add_arguments(parser)``: its options,
- ``run(args) -> int``: the exit code.

Command modules import heavy libraries (MuJoCo, Zenoh, OpenCV) inside ``run`` so that
``percept --help`` stays fast. A :class:`~percept.config.loader.ConfigError` anywhere ends the
program with exit code 2 and a message that names the file and the key.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import logging
import pkgutil
import sys
from collections.abc import Sequence
from types import ModuleType

from percept.config.loader import ConfigError
from percept.runtime import commands

EXIT_CONFIG = 2
# What a command that needs the simulated world says on a robot's install, which leaves MuJoCo out.
MISSING_SIMULATOR = (
    "this command needs the simulated world, which this install leaves out: "
    "pip install 'percept[sim]' (MuJoCo) and run it again"
)

log = logging.getLogger("percept.cli")


def _command_modules() -> list[ModuleType]:
    modules = [
        importlib.import_module(f"{commands.__name__}.{info.name}")
        for info in pkgutil.iter_modules(commands.__path__)
        if not info.name.startswith("_")
    ]
    return sorted(modules, key=lambda m: m.NAME)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="percept",
        description="Onboard perception runtime for robots that play language games.",
    )
    parser.add_argument("--version", action="version", version=f"percept {_version()}")
    _add_log_level(parser, default="INFO")
    # Every subcommand accepts --log-level too (``percept run --log-level DEBUG``); there it
    # defaults to "not given" so that it never overrides one given before the subcommand.
    common = argparse.ArgumentParser(add_help=False)
    _add_log_level(common, default=argparse.SUPPRESS)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in _command_modules():
        p = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP, parents=[common])
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def _version() -> str:
    """The installed package's version (pyproject.toml), or a word saying it is not installed."""
    try:
        return importlib.metadata.version("percept")
    except importlib.metadata.PackageNotFoundError:
        return "(not installed: run pip install -e .)"


def _add_log_level(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument(
        "--log-level",
        default=default,
        type=str.upper,
        choices=["DEBUG", "INFO", "WARNING", "ERROR"],
        help="log level for messages on stderr (default INFO)",
    )


def configure_logging(level: str) -> None:
    """Log lines with time, level and component on stderr."""
    logging.basicConfig(
        level=level,
        stream=sys.stderr,
        format="%(asctime)s %(levelname)-7s %(name)s: %(message)s",
    )


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    configure_logging(getattr(args, "log_level", "INFO"))
    try:
        return int(args._run(args) or 0)
    except ConfigError as err:
        print(f"percept: {err}", file=sys.stderr)
        return EXIT_CONFIG
    except ModuleNotFoundError as err:
        if err.name != "mujoco":
            raise
        print(f"percept: {MISSING_SIMULATOR}", file=sys.stderr)
        return EXIT_CONFIG
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
