"""What the daemon's status says of it: frame rate and cost, CPU and memory, when each peer was
last heard, floods by sender, and faults bounded so that the status stays a valid message."""

from __future__ import annotations

import collections
import math
import os
import resource
import statistics
import threading
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING

from percept.runtime.net.codec import JSON
from percept.runtime.net.messages import MAX_FAULTS, Status, clip

if TYPE_CHECKING:
    from percept.runtime.net.link import Traffic

FAULT_WORDS = 240  # characters of one fault at most
FLOOD_NAMES = 5  # senders a flood fault names at most


class Rate:
    """Frames per second and processing times over the last few seconds."""

    def __init__(self, window: float = 2.0) -> None:
        self.window = window
        self._times: collections.deque[float] = collections.deque()
        self._costs: collections.deque[float] = collections.deque(maxlen=256)

    def add(self, now: float, cost: float) -> None:
        self._times.append(now)
        self._costs.append(cost)
        while self._times and self._times[0] < now - self.window:
            self._times.popleft()

    def fps(self) -> float:
        times = self._times
        if len(times) < 2 or time.monotonic() - times[-1] > self.window:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def ms_median(self) -> float | None:
        return round(statistics.median(self._costs) * 1000, 2) if self._costs else None


class Cpu:
    """This process's CPU use (fraction of one core) since the last call."""

    def __init__(self) -> None:
        self._last = (time.monotonic(), time.process_time())

    def sample(self) -> float:
        now = (time.monotonic(), time.process_time())
        wall, cpu = now[0] - self._last[0], now[1] - self._last[1]
        self._last = now
        return round(cpu / wall, 3) if wall > 0 else 0.0


def resident_mb() -> float:
    """Resident memory of this process in MB (current, from /proc; peak where unavailable)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as fh:
            pages = int(fh.read().split()[1])
        return round(pages * os.sysconf("SC_PAGE_SIZE") / 1e6, 1)
    except (OSError, ValueError, IndexError):
        return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3, 1)


def finite(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else round(value, 4)


class Presence:
    """When each peer robot was last heard from (on the link's thread, whatever the frames do),
    and whether it left (its liveliness token went): the status's ``peers``."""

    def __init__(self, stale_after: float) -> None:
        self.stale_after = stale_after
        self._heard: dict[str, float] = {}
        self._lock = threading.Lock()

    def heard(self, name: str) -> None:
        with self._lock:
            self._heard[name] = time.monotonic()

    def gone(self, name: str) -> None:
        with self._lock:
            if name in self._heard:
                self._heard[name] = -math.inf

    def status(self, now: float) -> dict[str, dict[str, JSON]]:
        with self._lock:
            heard = list(self._heard.items())
        return {
            name: {"heard": now - last < self.stale_after, "age": finite(now - last)}
            for name, last in heard
        }


class Growth:
    """Whether a counter grew within the last ``window`` seconds."""

    def __init__(self, window: float) -> None:
        self.window = window
        self._value = 0
        self._when = -math.inf

    def grew(self, value: int, now: float) -> bool:
        if value > self._value:
            self._value, self._when = value, now
        return now - self._when <= self.window


def floods(traffic: Mapping[str, Traffic], prefix: str, bound: float) -> list[str]:
    """A fault per topic whose messages from other processes come faster than ``bound`` a
    second, naming the senders: one sender's key, or (many senders each under the bound
    together above it) the senders, sorted, the first few of them."""
    by_topic: dict[str, dict[str, float]] = {}
    for key, heard in traffic.items():
        if heard.rate > 0:
            by_topic.setdefault(heard.topic, {})[heard.robot or key] = heard.rate
    faults = []
    for topic, senders in sorted(by_topic.items()):
        if sum(senders.values()) <= bound:
            continue
        names = sorted(senders)
        if len(names) == 1:
            where = f"{prefix}/{names[0]}/{topic}"
        else:
            more = f" and {len(names) - FLOOD_NAMES} more" if len(names) > FLOOD_NAMES else ""
            where = f"{prefix}/*/{topic} from {', '.join(names[:FLOOD_NAMES])}{more}"
        faults.append(f"flood on {where}: more than {bound:g} messages/s")
    return faults


def reduced(status: Status) -> Status:
    """What is sent when the status fails its own check: the contract's counts and the faults
    (which name the failure), the free-form parts emptied."""
    return Status(
        robot=status.robot,
        stamp=status.stamp,
        fps=status.fps,
        dropped_frames=status.dropped_frames,
        camera={},
        servos={},
        peers={},
        rejected_messages=status.rejected_messages,
        faults=tuple(bounded(list(status.faults))),
    )


def bounded(faults: list[str]) -> list[str]:
    """At most ``MAX_FAULTS`` faults of at most :data:`FAULT_WORDS` characters: the status must
    stay a valid message whatever keys and payloads a babbling sender makes up."""

    short = [clip(f, FAULT_WORDS) for f in faults]
    if len(short) > MAX_FAULTS:
        short = [*short[: MAX_FAULTS - 1], "more faults than shown"]
    return short


def because(error: str | None) -> str:
    return f" ({error})" if error else ""
