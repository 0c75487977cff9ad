"""The ``--set JOINT=RADIANS`` option shared by the commands that take joint angles."""

from __future__ import annotations

import argparse
from collections.abc import Iterable


def add_set_option(p: argparse.ArgumentParser, help: str) -> None:
    p.add_argument("--set", action="append", default=[], metavar="JOINT=RADIANS", help=help)


def parse_angles(items: list[str], known: Iterable[str]) -> dict[str, float]:
    """``["head_pan=0.3"]`` -> ``{"head_pan": 0.3}``; a ValueError says what is wrong."""
    known = list(known)
    angles: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--set {item!r}: expected JOINT=RADIANS")
        if name not in known:
            raise ValueError(f"--set {item!r}: unknown joint {name!r}; known: {', '.join(known)}")
        try:
            angles[name] = float(value)
        except ValueError:
            raise ValueError(f"--set {item!r}: {value!r} is not a number") from None
    return angles
