"""What the daemon sends: its own messages checked on their way out, and the ``publisher`` thread.

Nothing that passed validation may stop the daemon, its own messages included: each is checked
as it is encoded, and one that fails is a bug of this daemon, not a reason to stop. It is not
sent but logged once per run of failures, counted (the status's ``unsent_messages``) and
reported among the faults while it goes on (:class:`Outbox`).

The ``publisher`` thread (:class:`Publisher`) sends the robot's box poses at the peers' box rate
and its status every ``status_interval`` seconds, and at once when the faults or the
background's phase change (its calibration begun or done: a calibration lasts about a second,
and whoever watches is to keep the scene empty meanwhile); it logs each fault when it appears
and when it clears.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING

from percept.runtime.daemon.status import health
from percept.runtime.daemon.status.faults import unsent_faults
from percept.runtime.incidents import Run
from percept.runtime.net.messages import Boxes, MessageError, encode

if TYPE_CHECKING:
    from percept.runtime.net.link import Link
    from percept.runtime.net.messages import BoxPose, Message, Status, World
    from percept.runtime.record.telemetry import Telemetry

log = logging.getLogger("percept.daemon")

FAULT_CHECK = 0.1  # seconds between looks at the faults (a change publishes the status at once)


class Outbox:
    """The daemon's own messages to ``link``: checked, sent, and counted when they fail.

    Thread-safe: the perception thread sends world models, the publisher boxes and status."""

    def __init__(self, link: Link, world_rate: float) -> None:
        self.link = link
        self.world_rate = world_rate
        """World models sent a second at most (0: every one); all are checked and recorded."""
        self._unsent: dict[str, Run] = {}  # by topic: own messages that failed their check
        self._lock = threading.Lock()
        self._last_world_sent = -math.inf

    def send(self, topic: str, message: Message) -> bool:
        """Publish one of this daemon's messages; whether it went (it fails its check)."""
        try:
            self.link.publish(topic, message)
        except MessageError as err:
            self._unsendable(topic, err)
            return False
        return True

    def world(self, world: World, now: float) -> bytes | None:
        """Check a frame's world model by encoding it and send it (at most :attr:`world_rate` a
        second); its payload, or None when it fails the check (then it is neither sent nor
        recorded)."""
        try:
            payload = encode(world)
        except MessageError as err:
            self._unsendable("world", err)
            return None
        rate = self.world_rate
        if rate <= 0 or now - self._last_world_sent >= 1.0 / rate:
            self._last_world_sent = now
            self.link.send("world", payload)
        return payload

    def unsent(self) -> int:
        """Own messages not sent since start because they failed their check."""
        with self._lock:
            return sum(run.total for run in self._unsent.values())

    def faults(self, now: float) -> list[str]:
        """The topics whose messages are failing their check now, in words."""
        with self._lock:
            return unsent_faults(self._unsent, now)

    def _unsendable(self, topic: str, err: MessageError) -> None:
        with self._lock:
            run = self._unsent.setdefault(topic, Run())
            began = run.add(str(err), time.monotonic())
        if began:
            log.error("own %s message not sent, it fails the check: %s", topic, err)


class Publisher:
    """The ``publisher`` thread's loop (:meth:`run`): box poses at ``box_rate`` a second, the
    status every ``status_interval`` seconds and at once when the faults or the background's
    ``phase`` change (looked at every :data:`FAULT_CHECK` seconds)."""

    def __init__(
        self,
        robot: str,
        outbox: Outbox,
        telemetry: Telemetry | None,
        boxes: Callable[[float], Iterable[BoxPose] | None],
        status: Callable[[], Status],
        faults: Callable[[], list[str]],
        phase: Callable[[], str],
        box_rate: float,
        status_interval: float,
        stop: threading.Event,
    ) -> None:
        self.robot = robot
        self.outbox = outbox
        self.telemetry = telemetry
        self._boxes = boxes  # at a monotonic time; None before the pipeline exists
        self._status = status
        self._faults = faults
        self._phase = phase
        self.box_interval = 1.0 / box_rate
        self.status_interval = status_interval
        self._stop = stop
        self.published: Status | None = None
        """The last status sent (None before the first)."""
        self._logged: set[str] = set()

    def run(self) -> None:
        next_boxes = next_status = next_check = time.monotonic()
        published: set[str] = set()
        phase = ""
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_boxes:
                next_boxes = max(next_boxes + self.box_interval, now)
                self._send_boxes(now)
            if now >= next_check:
                next_check = now + FAULT_CHECK
                if set(self._faults()) != published or self._phase() != phase:
                    next_status = now
            if now >= next_status:
                next_status = max(next_status + self.status_interval, now)
                phase = self._phase()
                published = set(self._send_status().faults)
            wake = min(next_boxes, next_status, next_check)
            self._stop.wait(max(0.0, wake - time.monotonic()))

    def _send_boxes(self, now: float) -> None:
        poses = self._boxes(now)
        if poses is None:
            return
        message = Boxes(self.robot, time.time(), tuple(poses))
        if self.outbox.send("boxes", message) and self.telemetry is not None:
            self.telemetry.log_boxes(message)

    def _send_status(self) -> Status:
        status = self._status()
        if not self.outbox.send("status", status):
            status = health.reduced(self._status())  # which now names the failure
            self.outbox.send("status", status)
        if self.telemetry is not None:
            self.telemetry.log_status(status)
        self.published = status
        self._log_faults(status.faults)
        return status

    def _log_faults(self, faults: tuple[str, ...]) -> None:
        """Log each fault when it appears and when it clears, not every second."""
        current = set(faults)
        for fault in sorted(current - self._logged):
            log.warning("fault: %s", fault)
        for fault in sorted(self._logged - current):
            log.info("cleared: %s", fault)
        self._logged = current
