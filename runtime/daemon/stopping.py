"""How ``percept run`` stops: within two seconds of SIGINT or SIGTERM, with no traceback.

The daemon runs on a thread of its own (:func:`run_until_stopped`), its loading included, so
that the main thread is always free to take a signal: a handler runs only between Python
bytecodes of the main thread, and loading and starting spend seconds inside C (importing
OpenCV and MuJoCo, loading a scene, opening a camera). A signal before the daemon opens
anything ends the process at once. The
main thread then waits for the daemon's own stop (recording closed first, then the devices and
the network) at most :data:`GRACE` seconds after the signal. Whatever has not finished by then
is abandoned: the process exits without joining its threads (``os._exit``). That is what
happens to numba compiling the kernels on a cold start (a compile cannot be interrupted from
Python and takes tens of seconds), and to a camera read or a renderer that does not return.
An exit that skips the devices' close is no worse for the servos than a kill, which they are
made to survive: a head under gaze has its bus watchdog armed and stops within a fraction of a
second when its writer goes silent.

Exit codes (:func:`exit_code`): 0 after SIGTERM, 130 after SIGINT (Ctrl-C, as shells count
it), 1 when the daemon failed or was stopped before it made a single world model (its log says
why), 2 when it refused to start (configuration, an unwritable ``--record``, its name taken).
A stop while the command line still loads, before the daemon starts, ends it with 128 + the
signal's number (130, 143). A second signal during the stop exits at once.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from types import FrameType

log = logging.getLogger("percept.run")

GRACE = 1.0
"""Seconds from a signal to the end of the process at the latest (the target is two)."""

Handler = Callable[[int, FrameType | None], object] | int | None
"""A signal's handler as :func:`signal.signal` takes and returns it."""

EXIT_FAILED = 1
EXIT_INTERRUPTED = 128 + signal.SIGINT  # 130


@dataclass
class StopRequest:
    """The signal that asked for the stop, and when (monotonic); set from a signal handler.

    Before the daemon starts (:meth:`starting`) a signal ends the process at once: nothing is
    open then, only files and modules being loaded. After, it sets :attr:`event`, the daemon
    stops, and :func:`run_until_stopped` sees that it does within :data:`GRACE` seconds."""

    event: threading.Event = field(default_factory=threading.Event)
    signum: int | None = None
    at: float | None = None
    unfinished: Callable[[], int | None] = lambda: None
    """The daemon's exit code if the process ended now (None: failed); set with the daemon."""
    _started: bool = False
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _previous: dict[int, Handler] = field(default_factory=dict, repr=False)

    def install(self) -> None:
        """Handle SIGINT and SIGTERM (from now on; call it on the main thread)."""
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._on_signal)

    def uninstall(self) -> None:
        """The handlers from before :meth:`install` (a caller in the same process goes on)."""
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    def starting(self) -> bool:
        """Called as the daemon is about to open its devices: whether it may (False: a stop
        was asked for and the process is ending)."""
        with self._lock:
            self._started = not self.event.is_set()
            return self._started

    def _on_signal(self, signum: int, _frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        if self.event.is_set():  # asked twice: the person means it
            log.warning("%s again: exiting without waiting for the stop", name)
            hard_exit(self.code(None))
        log.info("%s: stopping", name)
        with self._lock:
            self.signum, self.at = signum, time.monotonic()
            self.event.set()
            started = self._started
        if not started:
            log.info("stopped before the daemon started")
            hard_exit(128 + signum)  # as a shell counts a process a signal ended

    def code(self, daemon_code: int | None) -> int:
        """The exit code, given the daemon's (None: it has not finished; 0: it made world models
        and nothing failed)."""
        return exit_code(self.signum, daemon_code)


def exit_code(signum: int | None, daemon_code: int | None) -> int:
    """0 or 130 for a stop by SIGTERM or SIGINT after world models were made, else the daemon's
    code (1: failed, or none made); a daemon that has not finished counts as failed."""
    if daemon_code is None:
        return EXIT_FAILED
    if daemon_code == 0 and signum == signal.SIGINT:
        return EXIT_INTERRUPTED
    return daemon_code


def run_until_stopped(target: Callable[[], int], stop: StopRequest) -> int:
    """Run ``target`` (loading, then the daemon until ``stop.event`` is set and it has stopped)
    on a thread of its own, while this (the main) thread waits and takes the signals; the exit
    code. Once :data:`GRACE` seconds have passed since the signal, the process ends with
    ``stop.unfinished()``'s (:func:`hard_exit`). An exception of ``target`` is raised here."""
    outcome: list[int | BaseException] = []

    def work() -> None:
        try:
            outcome.append(target())
        except BaseException as err:  # given to the main thread, which reports it
            outcome.append(err)

    worker = threading.Thread(target=work, name="daemon", daemon=True)
    worker.start()
    while worker.is_alive():
        if stop.at is None:
            worker.join(0.1)  # short: the signal handler runs between these waits
            continue
        left = stop.at + GRACE - time.monotonic()
        if left <= 0:
            busy = ", ".join(sorted(t.name for t in _others()))
            log.warning("not stopped %.1f s after the signal: exiting (busy: %s)", GRACE, busy)
            hard_exit(stop.code(stop.unfinished()))
        worker.join(min(left, 0.1))
    result = outcome[0]
    if isinstance(result, BaseException):
        raise result
    return stop.code(result)


def _others() -> list[threading.Thread]:
    main = threading.main_thread()
    return [t for t in threading.enumerate() if t is not main and t.is_alive()]


def finish(code: int) -> int:
    """End the process with ``code`` now, its log written out (:func:`hard_exit`).

    Called once the daemon has closed what it opened. Python's own exit would join or tear
    down the threads still running: a thread pool's worker or a non-daemon thread is joined
    (the exit waits for it), and a thread inside native code is torn down under it, which can
    abort the process (LLVM compiling for numba: "terminate called without an active
    exception"); and on a busy machine the interpreter's finalization alone takes seconds."""
    others = _others()
    if others:
        log.debug("exiting past threads %s", ", ".join(sorted(t.name for t in others)))
    hard_exit(code)
    return code  # not reached


def hard_exit(code: int) -> None:
    """End the process with ``code`` at once, the log written out first; no thread is joined
    and no native destructor runs."""
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe: nothing more to say
            stream.flush()
    os._exit(code)
