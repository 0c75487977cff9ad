"""Joint angles over time: the contract between servo sources (a Dynamixel bus, simulated joints)
and their users (kinematics, the daemon).

A source keeps a :class:`JointHistory` of timestamped readings so that a camera frame taken at
monotonic time ``t`` can be matched with the joint angles at that same instant (interpolated),
together with how old the readings behind that answer are.
"""

from __future__ import annotations

import bisect
import math
import threading
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable


@dataclass(frozen=True)
class JointSample:
    """Joint angles in radians at monotonic time ``t``.

    ``age`` is how much older than ``t`` the newest reading behind the answer is, worst joint
    first (0 when ``t`` lies between two readings of every joint; it grows when ``t`` is later
    than the newest reading). ``stale`` names the joints whose servo stopped answering; their
    angle, if present, is their last known one.
    """

    angles: dict[str, float]
    t: float
    age: float
    stale: frozenset[str]


class _Track:
    """The readings of one joint, oldest first."""

    def __init__(self, capacity: int) -> None:
        self.times: deque[float] = deque(maxlen=capacity)
        self.values: deque[float] = deque(maxlen=capacity)

    def add(self, t: float, value: float) -> None:
        if self.times and t < self.times[-1]:
            # Out-of-order readings would break the sorted search; keep time monotonic.
            return
        self.times.append(t)
        self.values.append(value)

    def at(self, t: float) -> tuple[float, float]:
        """(angle at t, age of the newest reading used)."""
        times, values = self.times, self.values
        i = bisect.bisect_right(times, t)
        if i == len(times):
            return values[-1], t - times[-1]
        if i == 0:
            return values[0], 0.0
        t0, t1 = times[i - 1], times[i]
        v0, v1 = values[i - 1], values[i]
        if t1 == t0:
            return v1, 0.0
        w = (t - t0) / (t1 - t0)
        return v0 + w * (v1 - v0), 0.0


class JointHistory:
    """Thread-safe bounded history of joint readings, queried at any recent time.

    Each joint keeps its own ring buffer of ``capacity`` readings, so a joint missing from a
    reading (its servo did not answer) keeps its older readings and simply ages. Readings are
    interpolated linearly; a time later than the newest reading gets the newest angle and a
    growing ``age``; a time earlier than the oldest reading gets the oldest angle.
    """

    def __init__(self, capacity: int = 512) -> None:
        if capacity < 2:
            raise ValueError(f"capacity must be at least 2, got {capacity}")
        self._capacity = capacity
        self._tracks: dict[str, _Track] = {}
        self._stale: set[str] = set()
        self._lock = threading.Lock()

    def add(self, t: float, angles: Mapping[str, float]) -> None:
        """Record the angles read at monotonic time ``t``; a joint read again is no longer stale."""
        with self._lock:
            for name, value in angles.items():
                track = self._tracks.get(name)
                if track is None:
                    track = self._tracks[name] = _Track(self._capacity)
                track.add(t, float(value))
                self._stale.discard(name)

    def mark_stale(self, names: Iterable[str]) -> None:
        """Flag joints whose servo stopped answering (until they are read again)."""
        with self._lock:
            self._stale.update(names)

    def stale(self) -> frozenset[str]:
        """The joints currently flagged stale."""
        with self._lock:
            return frozenset(self._stale)

    def at(self, t: float) -> JointSample:
        """The angles at time ``t``; with no readings yet, no angles and an infinite age."""
        with self._lock:
            angles: dict[str, float] = {}
            age = -math.inf
            for name, track in self._tracks.items():
                angles[name], joint_age = track.at(t)
                age = max(age, joint_age)
            if not angles:
                age = math.inf
            return JointSample(angles=angles, t=t, age=max(age, 0.0), stale=frozenset(self._stale))

    def latest(self) -> JointSample | None:
        """The newest reading of every joint, at the time of the newest reading; None if empty."""
        with self._lock:
            if not self._tracks:
                return None
            t = max(track.times[-1] for track in self._tracks.values())
        return self.at(t)


@runtime_checkable
class JointSource(Protocol):
    """Something that reports joint angles over time: a servo bus or simulated joints.

    ``start`` and ``stop`` never raise for hardware trouble; the source reports it through
    ``status`` instead, a JSON-able dict with at least ``state`` ("connected", "reconnecting",
    "failed" or "stopped"), ``stale`` (joint names), ``errors`` (hardware errors in words, per
    joint), ``reads_per_s``, ``retries`` and ``reconnects``.
    """

    def start(self) -> None: ...

    def stop(self) -> None: ...

    def angles_at(self, t: float) -> JointSample | None:
        """The joint angles at monotonic time ``t``, or None before the first reading."""
        ...

    def status(self) -> dict[str, Any]: ...
