"""What the daemon's status says of it: frame rate and cost, CPU and memory, when each peer was
last heard, floods by sender, and faults bounded so that the status stays a valid message."""

from __future__ import annotations

import collections
import math
import os
import re
import resource
import statistics
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
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


MIN_INTERVAL = 0.25
"""Seconds: a CPU sample asked sooner after the last one is that last one again. A thread's time
is counted in clock ticks of a hundredth of a second, so over a shorter time its share would be
mostly rounding (a status asked twice in a row gave a thread 4552 cores)."""


class Cpu:
    """This process's CPU use since the last sample, in all and by thread (fractions of one
    core); safe to ask from several threads.

    A thread's share is read from ``/proc/self/task/<id>/stat`` (Linux; elsewhere there are no
    shares), in the kernel's clock ticks (a hundredth of a second here): over the status's
    second a share is good to about 0.01. Threads are named by the first word of their Python
    name (``camera``, ``perception``, ``markers``, ``percept-dynamixel``, ``publisher``, ``game``
    for each game's ``game <id>``...; those Python named by number as ``Thread``), those of one
    name summed; ``other`` is the rest of the process: the threads Python does not run
    (Zenoh's, the foxglove server's) and threads that ended since the last sample."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._last = (time.monotonic(), time.process_time())
        self._ticks = _thread_ticks()
        """Clock ticks of each thread (by native id) at the last sample."""
        self._sampled: tuple[float, dict[str, float]] = (0.0, {})

    def sample(self) -> tuple[float, dict[str, float]]:
        """The CPU used since the last sample, and its shares by thread name (the last sample's
        again when it is less than :data:`MIN_INTERVAL` old)."""
        with self._lock:
            now = (time.monotonic(), time.process_time())
            wall, cpu = now[0] - self._last[0], now[1] - self._last[1]
            if wall >= MIN_INTERVAL:
                ticks, before = _thread_ticks(), self._ticks
                self._last, self._ticks = now, ticks
                self._sampled = round(cpu / wall, 3), _shares(ticks, before, cpu, wall)
            total, shares = self._sampled
            return total, dict(shares)


def _shares(
    ticks: Mapping[int, int], before: Mapping[int, int], cpu: float, wall: float
) -> dict[str, float]:
    """The threads' shares of one core over ``wall`` seconds from their clock ``ticks`` now and
    ``before`` (by native id), ``other`` the rest of the process's ``cpu`` seconds."""
    names = {t.native_id: _role(t.name) for t in threading.enumerate()}
    used: dict[str, float] = collections.defaultdict(float)
    for tid, spent in ticks.items():
        name = names.get(tid)
        if name is None:
            continue
        # A thread that started since (or took the id of one that ended): all of its time.
        since = spent - before.get(tid, 0)
        used[name] += (since if since >= 0 else spent) / TICKS_PER_S
    if not used:
        return {}
    used["other"] = max(0.0, cpu - sum(used.values()))
    return {k: round(v / wall, 3) for k, v in sorted(used.items())}


def mean_shares(samples: Sequence[Mapping[str, float]]) -> dict[str, float]:
    """The mean share of each thread over ``samples`` (:meth:`Cpu.sample`'s, a thread missing
    from one counting 0 there), the largest first."""
    if not samples:
        return {}
    names = {name for shares in samples for name in shares}
    mean = {n: sum(shares.get(n, 0.0) for shares in samples) / len(samples) for n in names}
    return dict(sorted(mean.items(), key=lambda kv: -kv[1]))


def _role(name: str) -> str:
    """What a thread's share is reported under: the first word of its name, threads left
    unnamed (Python's ``Thread-7 (run)``, ``Dummy-2``) together."""
    return _NUMBERED.sub(r"\1", name.split(" ", 1)[0])


_NUMBERED = re.compile(r"^(Thread|Dummy)-\d+$")
TICKS_PER_S = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
"""The clock ticks of a second in which ``/proc`` counts CPU time (:func:`cpu_ticks`)."""


def cpu_ticks(stat: str | Path) -> int:
    """User and system clock ticks of a process or thread from its ``/proc/.../stat`` file."""
    # A native thread may name itself in any bytes.
    with open(stat, encoding="latin-1") as fh:
        # utime and stime are the 14th and 15th fields, the 12th and 13th after the command
        # name in parentheses (which may hold spaces).
        fields = fh.read().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])


def _thread_ticks() -> dict[int, int]:
    """:func:`cpu_ticks` of each thread of this process, by native thread id (empty without
    ``/proc``)."""
    out: dict[int, int] = {}
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return out
    for task in tasks:
        try:
            out[int(task)] = cpu_ticks(f"/proc/self/task/{task}/stat")
        except (OSError, ValueError, IndexError):
            continue  # a thread that ended meanwhile
    return out


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
