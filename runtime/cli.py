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
import os
import pkgutil
import sys
from collections.abc import Sequence
from types import ModuleType

from percept.config.loader import ConfigError
from percept.runtime import commands

EXIT_CONFIG = 2
EXIT_BROKEN_PIPE = 141
"""A reader that stopped reading (``percept config ... | head``): the shell's code for a program
ended by SIGPIPE, which Python ignores and turns into BrokenPipeError instead."""

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
        code = int(args._run(args) or 0)
        sys.stdout.flush()  # here, not at exit: a closed pipe is then caught below
        return code
    except ConfigError as err:
        print(f"percept: {err}", file=sys.stderr)
        return EXIT_CONFIG
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE


def _silence_stdout() -> None:
    """Point stdout at /dev/null: the interpreter flushes it on exit, and what is still buffered
    for a closed pipe would raise BrokenPipeError again there, as an 'Exception ignored' message."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


if __name__ == "__main__":
    sys.exit(main())
