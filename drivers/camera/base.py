"""The contract every camera source keeps: a reader thread and the freshest frame, never an old one.

A :class:`FrameSource` owns one thread that reads frames as they come and keeps only the newest;
the consumer asks for it with :meth:`FrameSource.latest` or :meth:`FrameSource.wait`. A frame older
than ``max_age`` is never handed out and no frame is handed out twice, so a slow consumer skips
frames (they are counted in ``dropped``) instead of falling behind a queue. Read failures and
unplugs are handled in the thread: it closes the source, reopens it with exponential backoff and
reports its :class:`CameraState`; nothing is raised into the caller's loop.

Subclasses implement ``_open``, ``_read`` and ``_close``; they are only ever called from the
reader thread, so a subclass needs no locking of its own.
"""

from __future__ import annotations

import abc
import collections
import enum
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from types import TracebackType
from typing import Any, Literal, Self

import numpy as np

from percept.drivers.camera.settings import CameraSettings

log = logging.getLogger("percept.camera")

_FPS_WINDOW = 2.0  # seconds of capture times the measured frame rate is averaged over
_JOIN_TIMEOUT = 1.0


GridColour = Literal["bgr", "ycrcb"]


@dataclass(frozen=True)
class Capture:
    """What one read gave when the source works at the grid's size: the image on the grid of
    every ``step``-th pixel (BGR, or YCrCb straight from a raw camera) and how to get the
    full-size BGR image, which is made only when something asks for it."""

    grid: np.ndarray
    step: int
    colour: GridColour
    full: Callable[[], np.ndarray]
    luma: Callable[[], np.ndarray] | None = None
    """How to get the full-size grey image from the source's own luma (a JPEG's, a raw frame's),
    without the BGR image; None: from the BGR image."""


@dataclass(frozen=True)
class Frame:
    """One captured image.

    ``image`` is BGR ``uint8`` of shape (height, width, 3), decoded when first read for a
    source that gives ``grid`` images; ``t`` is ``time.monotonic()`` at capture; ``seq``
    increases with every frame of a source and is never reused, also across reconnects;
    ``wall`` is ``time.time()`` at capture. ``grid`` (None: not made) is the image on the grid
    of every ``step``-th pixel, in ``grid_colour``: what perception works on. ``luma`` (None:
    not given) makes :attr:`gray` from the source's own data.
    """

    full: Callable[[], np.ndarray] = field(repr=False)
    t: float
    seq: int
    wall: float
    grid: np.ndarray | None = field(default=None, repr=False)
    step: int = 1
    grid_colour: GridColour = "bgr"
    luma: Callable[[], np.ndarray] | None = field(default=None, repr=False)

    @cached_property
    def image(self) -> np.ndarray:
        """The full-size BGR image (decoded on first use: only the frames that need it)."""
        return self.full()

    @cached_property
    def gray(self) -> np.ndarray:
        """The full-size grey image, what the marker search reads: the source's own luma where
        it has one (a JPEG decoded to grey, 1.1 ms at 640x480 against 3.7 ms to BGR and its
        conversion), else :attr:`image` converted. For one source always the same kind, whether
        or not the BGR image was made: recording a run or watching it leaves its markers alone."""
        return gray_image(lambda: self.image, self.luma)


class CameraState(enum.Enum):
    """What a source is doing; ``FAILED``, ``STOPPED`` and ``FINISHED`` are final."""

    CONNECTING = "connecting"
    CONNECTED = "connected"
    RECONNECTING = "reconnecting"
    FAILED = "failed"
    STOPPED = "stopped"
    FINISHED = "finished"


_FINAL = (CameraState.FAILED, CameraState.STOPPED, CameraState.FINISHED)


class CameraError(Exception):
    """A camera problem the caller has to act on (bad source description)."""


class SourceUnavailable(CameraError):
    """Raised by ``_open`` when retrying cannot help (no such file, no backend): ends ``FAILED``."""


class EndOfStream(CameraError):
    """Raised by ``_read`` at the end of a file or folder that does not loop: ends ``FINISHED``."""


class FrameSource(abc.ABC):
    """A camera read by one background thread that keeps only the newest frame.

    Use as a context manager or call :meth:`start` and :meth:`stop`. Set ``live = True`` in a
    subclass whose ``_read`` blocks until the device delivers (cameras pace themselves); other
    sources are paced by ``settings.pace``: ``"realtime"`` reads at ``settings.fps``,
    ``"lockstep"`` reads one frame each time the consumer asks for one, so a replay hands out
    every frame exactly once, whatever the consumer's speed. With ``settings.epoch`` the realtime
    rhythm is the epoch's: read ``i`` is due (and stamped) at ``epoch + i / fps``, a read
    overdue by more than a frame is skipped rather than caught up (:attr:`_read_number` says
    which read is due, for a source that can skip).
    """

    live: bool = False

    def __init__(self, settings: CameraSettings, grid_step: int = 1) -> None:
        self.settings = settings
        self.grid_step = grid_step
        """Perception's grid step: a source that can deliver frames at that size does
        (``Frame.grid``) and makes the full image only when asked; 1: full-size images only."""
        self._cond = threading.Condition()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._state = CameraState.CONNECTING
        self._slot: Frame | None = None  # newest frame not yet handed out
        self._wanted = False  # lockstep: the consumer asked for a frame
        self._seq = 0
        self._captured = 0
        self._dropped = 0
        self._stale = 0
        self._reconnects = 0
        self._error: str | None = None
        self._times: collections.deque[float] = collections.deque()
        self._epoch = 0.0  # settings.epoch as time.monotonic(), set on opening
        self._due = 0.0  # when the read under way was due (monotonic)

    # -- subclass interface (reader thread only) --------------------------------------------------

    @abc.abstractmethod
    def _open(self) -> None:
        """Open the source; raise to retry later, :class:`SourceUnavailable` to give up."""

    @abc.abstractmethod
    def _read(self) -> np.ndarray | Capture | None:
        """The next BGR image, or a :class:`Capture` on the grid of ``grid_step``; ``None`` or
        an exception is a failed read."""

    @abc.abstractmethod
    def _close(self) -> None:
        """Release the source; called after a successful ``_open`` only."""

    def _frame_time(self) -> float:
        """Monotonic time the image just read was taken; override when the source knows better.
        In step with an epoch, the time it was due."""
        return self._due if self._in_step else time.monotonic()

    @property
    def _in_step(self) -> bool:
        """Whether reads keep to ``settings.epoch``'s rhythm (a paced source given an epoch)."""
        return bool(self.settings.epoch) and self.settings.pace == "realtime" and not self.live

    @property
    def _read_number(self) -> int:
        """With ``settings.epoch``: the number of the read under way (0 at the epoch)."""
        return round((self._due - self._epoch) * self.settings.fps)

    # -- consumer interface -----------------------------------------------------------------------

    @property
    def state(self) -> CameraState:
        return self._state

    @property
    def dropped(self) -> int:
        """Frames captured but never handed out because a newer one replaced them."""
        return self._dropped

    def start(self) -> Self:
        """Start the reader thread (once)."""
        if self._thread is None:
            name = f"camera {self.settings.source}"
            self._thread = threading.Thread(target=self._run, name=name, daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the reader; returns within about a second even if a read hangs."""
        self._stopping.set()
        with self._cond:
            if self._state not in (CameraState.FAILED, CameraState.FINISHED):
                self._state = CameraState.STOPPED
            self._cond.notify_all()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(_JOIN_TIMEOUT)
            if self._thread.is_alive():
                log.warning("%s: reader still blocked in a read; it closes when that returns", self)

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    def latest(self, max_age: float | None = None) -> Frame | None:
        """The newest frame not handed out before and at most ``max_age`` seconds old, or None.

        ``max_age`` defaults to ``settings.max_age``. Never blocks.
        """
        with self._cond:
            return self._take(self._max_age(max_age))

    def wait(self, timeout: float, max_age: float | None = None) -> Frame | None:
        """Block up to ``timeout`` seconds for a fresh frame; None on timeout or a final state."""
        limit = self._max_age(max_age)
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                frame = self._take(limit)
                remaining = deadline - time.monotonic()
                if frame is not None or remaining <= 0 or self._state in _FINAL:
                    return frame
                self._cond.wait(remaining)

    def status(self) -> dict[str, Any]:
        """State and counters for ``percept.status/1``; every value is JSON-able."""
        with self._cond:
            return {
                "source": self.settings.source,
                "state": self._state.value,
                "fps": round(self._fps(), 2),
                "frames": self._captured,
                "dropped": self._dropped,
                "stale": self._stale,
                "reconnects": self._reconnects,
                "error": self._error,
            }

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.settings.source!r})"

    # -- internals --------------------------------------------------------------------------------

    def _max_age(self, max_age: float | None) -> float:
        return self.settings.max_age if max_age is None else max_age

    def _take(self, max_age: float) -> Frame | None:
        """Hand out the slot's frame if fresh enough; a stale one is discarded. Holds the lock."""
        frame, self._slot = self._slot, None
        if frame is not None and time.monotonic() - frame.t > max_age:
            self._stale += 1
            frame = None
        if frame is None and not self.live:
            self._wanted = True
            self._cond.notify_all()
        return frame

    def _fps(self) -> float:
        times = self._times
        while times and times[0] < time.monotonic() - _FPS_WINDOW:
            times.popleft()
        return (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0

    def _set(self, state: CameraState, error: str | None = None) -> None:
        with self._cond:
            if self._state is CameraState.STOPPED:
                return
            if state is not self._state:
                log.info("%s: %s%s", self, state.value, f" ({error})" if error else "")
            self._state = state
            if error is not None:
                self._error = error
            self._cond.notify_all()

    def _publish(self, image: np.ndarray | Capture) -> None:
        t = self._frame_time()
        wall = time.time() - (time.monotonic() - t)  # the same instant as t
        if isinstance(image, Capture):
            frame = Frame(
                image.full, t, self._seq, wall, image.grid, image.step, image.colour, image.luma
            )
        else:
            frame = Frame(_given(image), t, self._seq, wall)
        with self._cond:
            if self._slot is not None:
                self._dropped += 1
            self._slot = frame
            self._seq += 1
            self._captured += 1
            self._times.append(time.monotonic())
            self._wanted = False
            self._cond.notify_all()

    def _pause(self, due: float) -> float:
        """Wait until the next frame is due under ``settings.pace``; the next due time."""
        if self.live:
            return due
        if self.settings.pace == "lockstep":
            with self._cond:
                self._cond.wait_for(lambda: self._wanted or self._stopping.is_set())
            return due
        self._stopping.wait(max(0.0, due - time.monotonic()))
        period = 1.0 / self.settings.fps
        self._due = due
        if self._in_step:
            # in step with the epoch: late reads are skipped, the last one due is read
            behind = math.floor((time.monotonic() - due) * self.settings.fps)
            self._due = due + max(0, behind) * period
            return self._due + period
        # after a long stall, restart the rhythm instead of bursting to catch up
        return max(due, time.monotonic() - period) + period

    def _first_due(self) -> float:
        """When the first read after opening is due: now, or the epoch if it is still to come
        (a later one is skipped to by :meth:`_pause`)."""
        now = time.monotonic()
        if not self._in_step:
            return now
        self._epoch = self.settings.epoch - time.time() + now
        return max(self._epoch, now - (now - self._epoch) % (1.0 / self.settings.fps))

    def _run(self) -> None:
        first, largest = self.settings.reconnect_backoff
        backoff = first
        opened = ever_opened = False
        failures = 0
        due = time.monotonic()
        try:
            while not self._stopping.is_set():
                if not opened:
                    try:
                        self._open()
                    except SourceUnavailable as err:
                        self._set(CameraState.FAILED, str(err))
                        return
                    except Exception as err:
                        self._set(CameraState.RECONNECTING, f"cannot open: {_words(err)}")
                        self._stopping.wait(backoff)
                        backoff = min(2.0 * backoff, largest)
                        continue
                    opened, failures, backoff = True, 0, first
                    if ever_opened:
                        self._reconnects += 1
                    ever_opened = True
                    self._set(CameraState.CONNECTED)
                    due = self._first_due()
                due = self._pause(due)
                if self._stopping.is_set():
                    break
                try:
                    image = self._read()
                    problem = "read returned no image"
                except EndOfStream:
                    self._set(CameraState.FINISHED)
                    return
                except Exception as err:
                    image, problem = None, f"read failed: {_words(err)}"
                if image is not None:
                    failures = 0
                    self._publish(image)
                    continue
                failures += 1
                if failures >= self.settings.max_failures:
                    self._set(CameraState.RECONNECTING, f"{failures} failed reads; {problem}")
                    opened = False
                    self._close_quietly()
                    self._stopping.wait(backoff)
                    backoff = min(2.0 * backoff, largest)
        except Exception as err:  # a bug must not kill the caller; say it in status
            log.exception("%s: reader crashed", self)
            self._set(CameraState.FAILED, f"reader crashed: {_words(err)}")
        finally:
            if opened:
                self._close_quietly()

    def _close_quietly(self) -> None:
        try:
            self._close()
        except Exception as err:
            log.warning("%s: close failed: %s", self, _words(err))


def gray_image(full: Callable[[], np.ndarray], luma: Callable[[], np.ndarray] | None) -> np.ndarray:
    """The full-size grey image of a frame whose BGR image ``full`` gives: from the source's own
    ``luma`` where it has one (no BGR image made), else the BGR image converted."""
    if luma is not None:
        return luma()
    import cv2

    return cv2.cvtColor(full(), cv2.COLOR_BGR2GRAY)


def _given(image: np.ndarray) -> Callable[[], np.ndarray]:
    """The full image of a frame read at full size."""
    return lambda: image


def _words(err: BaseException) -> str:
    return str(err) or type(err).__name__
