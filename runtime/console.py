"""The line a person watches on a terminal: how a robot is doing, once a second.

``percept run`` shows its robot's line in place at the bottom of the terminal (:class:`Console`);
``percept demo`` shows one part per robot in its progress line (:func:`robot_part`). Both read
what the daemon publishes anyway: its status (``percept.status/1``) and its last world model.
Before the background model is made the line says how far its calibration is; afterwards it
gives frames per second, anchors (objects seen or remembered), marker boxes, the peers located
(whose pose it knows), the games won and played, and the faults.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
from collections.abc import Callable
from typing import TextIO

from percept.runtime.net.messages import Status, World

PERIOD = 1.0  # seconds between two lines
NO_BACKGROUND = "no background model yet"  # a fault the calibration's progress already says

Latest = Callable[[], tuple[Status | None, World | None]]
"""The status last published and the last world model (None before the first)."""


def wanted(quiet: bool) -> bool:
    """Whether to show the line: not asked to be quiet, and both stdout and stderr are a
    terminal (a run whose output goes to a file or a pipe gets the log only)."""
    return not quiet and sys.stdout.isatty() and sys.stderr.isatty()


def robot_part(status: Status | None, world: World | None) -> str:
    """A robot's state: starting, its background calibration, or its rate, anchors, boxes and
    the peers it located."""
    if status is None:
        return "starting"
    background = status.background
    if not background.startswith(("calibrated", "loaded")):
        # No frame rate before the background model: what it does instead of 0 fps.
        return f"background {background} (keep the scene empty)"
    fps = f"{status.fps:4.1f}" if status.fps > 0 else "   -"  # 0 until measured over frames
    anchors = 0 if world is None else len(world.objects)
    boxes = 0 if world is None else len(world.boxes)
    located = "" if world is None else ",".join(world.peers)  # peers whose pose it knows
    return f"{fps} fps {anchors} anchors {boxes} boxes peer {located or '-'}"


def games_part(status: Status) -> str:
    """The games this robot took part in: pointing and guessing games won of played, and the
    words its agent knows."""
    g = status.games
    return (
        f"pointing {g.get('success', 0)}/{g.get('played', 0)}"
        f" guessing {g.get('guessing_success', 0)}/{g.get('guessing_played', 0)}"
        f" ({g.get('lexicon_size', 0)} words)"
    )


def faults_part(status: Status) -> str:
    """The faults in words, or ``no faults``."""
    faults = [f for f in status.faults if f != NO_BACKGROUND]
    if not faults:
        return "no faults"
    return f"{len(faults)} fault{'s' if len(faults) > 1 else ''}: " + "; ".join(faults)


def status_line(status: Status | None, world: World | None) -> str:
    """``percept run``'s line: robot, state, games and faults."""
    if status is None:
        return "starting: opening the camera and the servos, loading the kernels"
    parts = [status.robot, robot_part(status, world)]
    if status.background.startswith(("calibrated", "loaded")):
        parts.append(games_part(status))
    parts.append(faults_part(status))
    return " | ".join(parts)


class Console:
    """Shows ``line()`` every :data:`PERIOD` seconds in place on ``stream`` (a terminal), the log
    records written meanwhile going above it. Use as a context manager; at the end the last
    line stays on the screen."""

    def __init__(self, line: Callable[[], str], stream: TextIO | None = None) -> None:
        self._line = line
        self._stream = stream if stream is not None else sys.stderr
        self._lock = threading.Lock()
        self._shown = ""  # the line on the screen now ("" after a log record cleared it)
        self._last = ""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="console", daemon=True)
        self._handlers: list[tuple[logging.StreamHandler[TextIO], TextIO]] = []

    def __enter__(self) -> Console:
        # The log handlers writing to this terminal write through this console: each record
        # clears the line first and the line comes back under it.
        for handler in logging.getLogger().handlers:
            if isinstance(handler, logging.StreamHandler) and handler.stream is self._stream:
                self._handlers.append((handler, handler.stream))
                handler.setStream(_Above(self))
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._thread.join()
        with self._lock:
            if self._shown:
                self._stream.write("\n")
                self._stream.flush()
            self._shown = ""
        for handler, stream in self._handlers:
            handler.setStream(stream)

    def _loop(self) -> None:
        while True:
            try:
                text = self._line()
            except Exception as err:  # the console never stops the run
                text = f"(console: {err})"
            self._show(text)
            if self._stop.wait(PERIOD):
                return

    def _show(self, text: str) -> None:
        width = _width(self._stream)
        if len(text) > width - 1:  # one terminal row: a wrapped line would not be redrawn
            text = text[: width - 2] + "…"
        with self._lock:
            self._last = text
            self._stream.write("\r\x1b[K" + text)
            self._stream.flush()
            self._shown = text

    def write_above(self, text: str) -> None:
        """Write ``text`` (log output) above the line, then show the line again."""
        with self._lock:
            if self._shown:
                self._stream.write("\r\x1b[K")
                self._shown = ""
            self._stream.write(text)
            if text.endswith("\n") and self._last and not self._stop.is_set():
                self._stream.write(self._last)
                self._shown = self._last
            self._stream.flush()


class _Above:
    """A log handler's stream that writes above the console's line."""

    def __init__(self, console: Console) -> None:
        self._console = console

    def write(self, text: str) -> int:
        self._console.write_above(text)
        return len(text)

    def flush(self) -> None:
        pass  # write_above flushes


def _width(stream: TextIO) -> int:
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (OSError, ValueError):
        return 120
