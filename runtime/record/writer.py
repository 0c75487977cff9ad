"""An MCAP file being written by a daemon, on a thread of its own: its name (never an existing
file's), its lock, its chunks flushed on time, and what happens when the disk fills up or the
file is removed, moved or replaced while it is written."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import itertools
import logging
import os
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from percept.runtime.net.codec import JSON

if TYPE_CHECKING:
    from foxglove.mcap import MCAPWriter

log = logging.getLogger("percept.recording")

LOST_FAULT = 60.0
"""Seconds a file that went away while it was written stays among the status's faults (the
status's ``recording.lost`` keeps it for the whole run)."""
LOST_KEPT = 8  # files that went away listed in the status, the latest


def _went(held: int, path: Path) -> str | None:
    """How the file open as ``held`` left ``path``: "removed" or "replaced" (by another file
    of that name: no name has it any more, what was written to it goes with the last
    descriptor), "moved" (it has another name), or None: it is still there."""
    kept = os.fstat(held)
    try:
        now = os.stat(path)
    except FileNotFoundError:
        return "removed" if kept.st_nlink == 0 else "moved"
    if (now.st_dev, now.st_ino) == (kept.st_dev, kept.st_ino):
        return None
    return "replaced" if kept.st_nlink == 0 else "moved"


def _fate(how: str) -> str:
    return "kept in it" if how == "moved" else "lost with it"


def lost_faults(recording: Mapping[str, JSON], now: float) -> list[str]:
    """The status's faults for the files of ``recording`` (a status's ``recording``) that went
    away in the last :data:`LOST_FAULT` seconds (``now``: wall-clock time)."""
    faults = []
    lost = recording.get("lost")
    for entry in lost if isinstance(lost, list) else ():
        if not isinstance(entry, dict):
            continue
        at = entry.get("at")
        if isinstance(at, int | float) and now - at <= LOST_FAULT:
            how = str(entry.get("how"))
            faults.append(
                f"recording file {entry.get('file')} was {how} while recorded "
                f"(what it held is {_fate(how)}); recording goes on in {entry.get('then')}"
            )
    return faults


class Recorder:
    """An MCAP file being written, on a thread of its own.

    The current chunk is closed every ``flush_interval`` seconds, so a crash loses at most that
    much. A write that fails (disk full: foxglove-sdk then refuses every later write to the
    file) gives the file up: it is closed as far as it goes and reads to its last flush. Every
    ``retry_interval`` seconds the disk is probed, and once it takes data again recording goes
    on in a continuation file with the same metadata and attachments.

    Every file, the first and the continuations, takes the first free name of ``path``,
    ``<stem>.1.mcap``, ``<stem>.2.mcap``, ... that this recording has not used: it is created
    exclusively (an existing file, an earlier recording or another process's, is never opened)
    and locked (``flock``) while it is written, which tells a second process that it is in use.

    At every flush the file is looked for under its name. One that was removed, moved or
    replaced (``rm a.mcap``) is closed and recording goes on at once in a continuation file:
    what was logged until that look (at most ``flush_interval`` seconds after the file went
    away) went into the file that went away, what comes after into the continuation. The
    status lists such files (``lost``), and for :data:`LOST_FAULT` seconds a fault says so.
    """

    def __init__(
        self,
        open_writer: Callable[[Path], MCAPWriter],
        path: Path,
        metadata: dict[str, str],
        flush_interval: float,
        retry_interval: float,
    ) -> None:
        self._open_writer = open_writer
        self._first = path
        self._metadata = metadata
        self._attachments: list[tuple[str, bytes, str]] = []
        self._flush_interval = flush_interval
        self._retry_interval = retry_interval
        self._lock = threading.Lock()
        self._held: int | None = None  # the descriptor holding the current file's flock
        self._files: list[Path] = []
        self.kept: list[Path] = []  # existing files the first one was not written to
        self._lost: list[dict[str, JSON]] = []  # files that went away while written
        # a first file that cannot be opened is an error
        self._writer: MCAPWriter | None = self._start()
        self._error: str | None = None
        self._flushed = time.time()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mcap recorder", daemon=True)
        self._thread.start()

    def _start(self) -> MCAPWriter:
        """Open the first free name, lock it, and write the metadata and attachments."""
        if self._first.is_dir():  # not a recording to keep: a mistake
            raise IsADirectoryError(errno.EISDIR, "a folder, not a file", str(self._first))
        for path in recording_names(self._first):
            if path in self._files:  # this recording's own, even if it is gone now
                continue
            if not path.exists():
                try:
                    writer = self._open_writer(path)
                    break
                except FileExistsError:  # created by another process since the look
                    pass
            if not self._files:
                self.kept.append(path)
        self._files.append(path)
        self._release()
        try:
            self._held = _lock(path)
            writer.write_metadata("percept", dict(self._metadata))
            for name, data, media_type in self._attachments:
                _attach(writer, name, data, media_type)
        except Exception:
            _close_quietly(writer)
            raise
        return writer

    def _release(self) -> None:
        if self._held is not None:
            os.close(self._held)  # the flock goes with the descriptor
            self._held = None

    def attach(self, name: str, data: bytes, media_type: str) -> None:
        with self._lock:
            self._attachments.append((name, data, media_type))
            if self._writer is not None:
                try:
                    _attach(self._writer, name, data, media_type)
                except Exception as err:
                    self._fail(err)

    def status(self) -> dict[str, JSON]:
        with self._lock:
            return {
                "state": "recording" if self._writer is not None else "failed",
                "file": str(self._files[-1]),
                "files": [str(f) for f in self._files],
                "error": self._error,
                "flushed": round(self._flushed, 3),
                "lost": list(self._lost),
            }

    def _run(self) -> None:
        next_retry = 0.0
        while not self._stop.wait(self._flush_interval):
            with self._lock:
                if self._writer is not None:
                    try:
                        self._writer.flush()
                        self._flushed = time.time()
                    except Exception as err:  # a full disk must not stop perception
                        self._fail(err)
                        next_retry = time.monotonic() + self._retry_interval
                    else:
                        self._look_for_file()
                elif time.monotonic() >= next_retry:
                    self._retry()
                    next_retry = time.monotonic() + self._retry_interval

    def _look_for_file(self) -> None:
        """Go on in a new file if the current one left its name (lock held)."""
        if self._held is None:
            return
        how = _went(self._held, self._files[-1])
        if how is None:
            return
        gone, writer, held = self._files[-1], self._writer, self._held
        self._held = None  # kept until the new file is open: nothing logged meanwhile is lost
        try:
            self._writer = self._start()
        except Exception as err:  # the folder went too, say: tried again as after a full disk
            self._writer, self._error = None, _words(err)
            if self._files[-1] != gone:  # created, but it does not take data: not kept
                self._files.pop().unlink(missing_ok=True)
                self._release()
        _close_quietly(writer)  # the rest of the file that went away, complete
        os.close(held)
        then = str(self._files[-1]) if self._writer is not None else "a new file when it can"
        self._lost = [*self._lost, {"file": str(gone), "how": how, "at": time.time(), "then": then}]
        self._lost = self._lost[-LOST_KEPT:]
        log.error(
            "recording file %s was %s while recorded (what it held is %s); recording goes on in %s",
            gone,
            how,
            _fate(how),
            then,
        )

    def _fail(self, err: Exception) -> None:
        """Give the current file up (lock held)."""
        self._error = _disk_problem(self._files[-1].parent) or _words(err)
        log.error(
            "recording to %s failed: %s; the file keeps everything up to %s; recording goes on "
            "in a new file when the disk takes data again",
            self._files[-1],
            self._error,
            time.strftime("%H:%M:%S", time.localtime(self._flushed)),
        )
        _close_quietly(self._writer)
        self._writer = None
        self._release()

    def _retry(self) -> None:
        """Open a continuation file if the disk takes data again (lock held)."""
        problem = _disk_problem(self._first.parent)
        if problem is not None:
            self._error = problem
            return
        files = len(self._files)
        writer = None
        try:
            writer = self._start()
            writer.flush()
        except Exception as err:
            self._error = _words(err)
            _close_quietly(writer)
            if len(self._files) > files:  # created, but it does not take data: not kept
                self._files.pop().unlink(missing_ok=True)
                self._release()
            return
        self._writer, self._error, self._flushed = writer, None, time.time()
        log.warning("recording goes on in %s", self._files[-1])

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        with self._lock:
            if self._writer is not None:
                try:
                    self._writer.close()
                    log.info("recording closed")
                except Exception as err:
                    log.error("closing the recording %s failed: %s", self._files[-1], err)
                self._writer = None
            self._release()


class _Repeats(logging.Filter):
    """Lets each distinct line through once every ``interval`` seconds: after a failed write
    foxglove-sdk logs every message the file refuses (dozens a second) until it is closed."""

    def __init__(self, interval: float = 10.0) -> None:
        super().__init__()
        self._interval = interval
        self._last: dict[str, float] = {}

    def filter(self, record: logging.LogRecord) -> bool:
        text, now = record.getMessage(), time.monotonic()
        if now - self._last.get(text, -self._interval) < self._interval:
            return False
        if len(self._last) > 64:
            self._last.clear()
        self._last[text] = now
        return True


def quiet_sdk_repeats() -> None:
    sdk = logging.getLogger("foxglove.log_sink_set")
    if not any(isinstance(f, _Repeats) for f in sdk.filters):
        sdk.addFilter(_Repeats())


def recording_names(first: Path) -> Iterator[Path]:
    """The names tried, in order, for a recording asked for as ``first`` (``a.mcap``,
    ``a.1.mcap``, ``a.2.mcap``, ...); it takes the first that does not exist."""
    yield first
    for n in itertools.count(1):
        yield first.with_name(f"{first.stem}.{n}{first.suffix}")


def free_name(first: Path) -> Path:
    """The name a recording asked for as ``first`` gets now (for a reader that must know it)."""
    return next(p for p in recording_names(first) if not p.exists())


def _lock(path: Path, wait: bool = True) -> int:
    """A descriptor holding an exclusive ``flock`` on ``path`` (released when it is closed,
    or when the process dies however it dies); ``wait`` False: BlockingIOError if it is held."""
    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise
    return fd


def locked(path: Path) -> bool:
    """Whether a running process holds ``path``'s lock (is writing it)."""
    try:
        os.close(_lock(path, wait=False))  # a writer's own lock waits out this probe
    except BlockingIOError:
        return True
    except OSError:
        return False
    return False


def _attach(writer: MCAPWriter, name: str, data: bytes, media_type: str) -> None:
    now = time.time_ns()
    writer.attach(log_time=now, create_time=now, name=name, media_type=media_type, data=data)


def _close_quietly(writer: MCAPWriter | None) -> None:
    """Close a writer whose file is given up; it detaches from the context even if it fails."""
    if writer is not None:
        with contextlib.suppress(Exception):
            writer.close()


_PROBE_BYTES = 64 * 1024


def _disk_problem(directory: Path) -> str | None:
    """Why ``directory`` does not take data now (``No space left on device``), or None: a
    probe file is written, synced and removed."""
    probe = directory / f".percept-probe-{os.getpid()}"
    try:
        with open(probe, "wb") as fh:
            fh.write(bytes(_PROBE_BYTES))
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as err:
        return err.strerror or str(err)
    finally:
        with contextlib.suppress(OSError):
            probe.unlink()
    return None


def _words(err: BaseException) -> str:
    return str(err) or type(err).__name__
