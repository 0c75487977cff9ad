"""The ``percept`` command line.

Each subcommand is one module in a subpackage of :mod:`percept.runtime.commands` (one per kind
of work) with four names:

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
import logging
import os
import pkgutil
import signal
import sys
import threading
from collections.abc import Sequence
from types import ModuleType

EXIT_CONFIG = 2
EXIT_BROKEN_PIPE = 141
"""A reader that stopped reading (``percept config ... | head``): the shell's code for a program
ended by SIGPIPE, which Python ignores and turns into BrokenPipeError instead."""

log = logging.getLogger("percept.cli")


def _command_modules() -> list[ModuleType]:
    """Every subcommand's module: the modules of :mod:`percept.runtime.commands`'s subpackages
    whose names do not start with ``_`` (those hold what several commands share)."""
    from percept.runtime import commands

    modules = [
        importlib.import_module(f"{package.name}.{info.name}")
        for package in pkgutil.iter_modules(commands.__path__, f"{commands.__name__}.")
        if package.ispkg
        for info in pkgutil.iter_modules(importlib.import_module(package.name).__path__)
        if not info.name.startswith("_")
    ]
    return sorted(modules, key=lambda m: m.NAME)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="percept",
        description="Onboard perception runtime for robots that play language games.",
    )
    parser.add_argument("--version", action=_VersionAction)
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


class _VersionAction(argparse.Action):
    """``--version``: the version is looked up only when asked (the package metadata takes a
    twentieth of a second of every command's start otherwise)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **_: object) -> None:
        super().__init__(
            option_strings, argparse.SUPPRESS, nargs=0, help="show the version and exit"
        )

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: object,
        values: object,
        option_string: str | None = None,
    ) -> None:
        print(f"percept {_version()}")
        parser.exit()


def _version() -> str:
    """The installed package's version (pyproject.toml), or a word saying it is not installed."""
    import importlib.metadata  # here, not at the top: see main()

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


class _Stopped(KeyboardInterrupt):
    """SIGINT or SIGTERM while the command line loads; ``code`` as a shell counts a process
    a signal ended."""

    def __init__(self, signum: int) -> None:
        super().__init__()
        self.code = 128 + signum


def _stopped_while_loading(signum: int, _frame: object) -> None:
    raise _Stopped(signum)


def main(argv: Sequence[str] | None = None) -> int:
    # This module imports little: the parser imports the commands' modules, which takes a
    # second or more on a busy machine, and SIGINT or SIGTERM meanwhile ends the program
    # quietly (a command then handles them as it says, e.g. percept run).
    quiet = threading.current_thread() is threading.main_thread()
    if quiet:
        previous = {s: signal.signal(s, _stopped_while_loading) for s in _STOPS}
    try:
        args = build_parser().parse_args(argv)
        if quiet:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        configure_logging(getattr(args, "log_level", "INFO"))
        code = int(args._run(args) or 0)
        sys.stdout.flush()  # here, not at exit: a closed pipe is then caught below
        return code
    except _Stopped as stop:
        return stop.code
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except ModuleNotFoundError as err:
        # An optional part a robot's install leaves out (percept.config.extras): named, with
        # the extra that brings it. Any other missing module is a broken install: raised.
        from percept.config.extras import missing

        why = missing(err.name or "")
        if why is None:
            raise
        print(f"percept: this command {why}", file=sys.stderr)
        return EXIT_CONFIG
    except Exception as err:
        from percept.config.loader import ConfigError

        if not isinstance(err, ConfigError):
            raise
        print(f"percept: {err}", file=sys.stderr)
        return EXIT_CONFIG


_STOPS = (signal.SIGINT, signal.SIGTERM)


def _silence_stdout() -> None:
    """Point stdout at /dev/null: the interpreter flushes it on exit, and what is still buffered
    for a closed pipe would raise BrokenPipeError again there, as an 'Exception ignored' message."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


if __name__ == "__main__":
    sys.exit(main())
