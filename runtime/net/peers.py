"""Where the peer robots stand: box poses traded at 5 Hz and the pose they imply (SPEC §4.7).

Each robot publishes the boxes it sees in its own ground frame about five times a second. A box
``b = (x_b, y_b, theta_b)`` seen by me and the same box ``b' = (x'_b, y'_b, theta'_b)`` seen by
the peer in its frame give the peer's pose in my frame::

    theta_r = theta_b - theta'_b
    x_r = x_b - cos(theta_r) x'_b + sin(theta_r) y'_b
    y_r = y_b - sin(theta_r) x'_b - cos(theta_r) y'_b

(the chapter's y row repeats its x row; this is the corrected one). With several shared boxes the
headings are averaged by circular mean first, then the positions with that common heading.

A box message passes the schema with boxes ten kilometres away; the experiment knows better. A
peer's box farther than ``[peers] arena`` from the peer, or a peer pose farther than that from
me, is implausible: rejected, and counted by sender with the first reason of each run
(:meth:`PeerTracker.implausible`), so that one bad (or buggy) peer cannot put nonsense into the
world model. So is a box message stamped :data:`FAR_STAMPS` times ``[peers] stale_after`` or
more before or after its arrival (a stamp of 1970 or of yesterday is no fresh pose; the margin
takes clocks that disagree by seconds).
"""

from __future__ import annotations

import copy
import logging
import math
import threading
import time
from collections.abc import Callable, Iterable

import numpy as np

from percept.perception.landmarks.geometry import circular_mean
from percept.perception.landmarks.records import BoxPose
from percept.runtime.incidents import Run
from percept.runtime.net.link import Link, LinkError
from percept.runtime.net.messages import Boxes, PeerPose
from percept.runtime.net.settings import PeerSettings

log = logging.getLogger("percept.peers")

FAR_STAMPS = 10.0  # a box stamp this many stale_after from its arrival is implausible


def rotate(theta: float, x: float, y: float) -> tuple[float, float]:
    """``R(theta) (x, y)``."""
    c, s = math.cos(theta), math.sin(theta)
    return c * x - s * y, s * x + c * y


def to_my_frame(peer: PeerPose, x: float, y: float) -> tuple[float, float]:
    """A point ``(x, y)`` of the peer's frame in mine: ``R(theta_r) (x, y) + (x_r, y_r)``."""
    u, v = rotate(peer.theta, x, y)
    return u + peer.x, v + peer.y


def to_peer_frame(peer: PeerPose, x: float, y: float) -> tuple[float, float]:
    """A point ``(x, y)`` of my frame in the peer's: the inverse of :func:`to_my_frame`."""
    return rotate(-peer.theta, x - peer.x, y - peer.y)


def inverse(peer: PeerPose) -> PeerPose:
    """My pose in the peer's frame, from the peer's pose in mine."""
    x, y = rotate(-peer.theta, -peer.x, -peer.y)
    theta = math.atan2(math.sin(-peer.theta), math.cos(-peer.theta))
    return PeerPose(x, y, theta, peer.stamp, peer.n_boxes)


def peer_pose(
    mine: Iterable[BoxPose], theirs: Iterable[BoxPose], stamp: float = 0.0
) -> PeerPose | None:
    """The peer's pose in my frame from the boxes we both see (None when we share none)."""
    by_id = {b.id: b for b in theirs}
    shared = [(b, by_id[b.id]) for b in mine if b.id in by_id]
    if not shared:
        return None
    theta = circular_mean(b.theta - p.theta for b, p in shared)
    offsets = [
        (b.x - rotate(theta, p.x, p.y)[0], b.y - rotate(theta, p.x, p.y)[1]) for b, p in shared
    ]
    x, y = np.mean(offsets, axis=0)
    return PeerPose(float(x), float(y), theta, stamp, len(shared))


class PeerTracker:
    """Each peer's latest box message and the pose it gives against my own boxes.

    Thread-safe. A peer not heard for ``stale_after`` seconds, or whose liveliness token went
    away, has no pose; nor has one whose boxes or pose lie beyond the arena (see the module doc).
    """

    def __init__(
        self,
        me: str,
        my_boxes: Callable[[], list[BoxPose]],
        settings: PeerSettings | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.me = me
        self.settings = settings or PeerSettings()
        self._my_boxes = my_boxes
        self._clock = clock
        self._latest: dict[str, tuple[float, Boxes]] = {}
        self._implausible: dict[str, Run] = {}
        self._judged: dict[str, Boxes] = {}  # the message whose pose was last found implausible
        self._lock = threading.Lock()

    def on_boxes(self, message: Boxes, wall: float | None = None) -> None:
        """A peer's box message arrived (a :class:`~percept.runtime.net.link.Link` handler);
        ``wall``: the wall-clock time it arrived (None: its stamp is not checked)."""
        if message.robot == self.me:
            return
        margin = FAR_STAMPS * self.settings.stale_after
        if wall is not None and abs(message.stamp - wall) > margin:
            off = message.stamp - wall
            when = f"{abs(off):.4g} s {'after' if off > 0 else 'before'} it arrived"
            self._reject(message.robot, f"stamped {when}, more than {margin:g} s")
            return
        arena = self.settings.arena
        far = next((b for b in message.boxes if math.hypot(b.x, b.y) > arena), None)
        if far is not None:
            where = f"box {far.id} {math.hypot(far.x, far.y):.4g} m from it"
            self._reject(message.robot, f"{where}, beyond the arena ({arena:g} m)")
            return
        with self._lock:
            self._latest[message.robot] = (self._clock(), message)

    def _reject(self, peer: str, reason: str) -> None:
        with self._lock:
            # Only the experiment's robots reach a tracker (the daemon drops other senders),
            # so this table stays small.
            run = self._implausible.setdefault(peer, Run())
            began = run.add(reason, self._clock())
        if began:
            log.warning("implausible data from peer %s rejected: %s", peer, reason)

    def implausible(self) -> dict[str, Run]:
        """Per peer, its implausible data so far (copies; ``active`` on this tracker's clock)."""
        with self._lock:
            return {name: copy.copy(run) for name, run in self._implausible.items()}

    def on_alive(self, name: str, alive: bool) -> None:
        """A liveliness change (a :class:`~percept.runtime.net.link.Link` handler): a peer that is
        gone has no pose from this moment on."""
        if not alive:
            with self._lock:
                if self._latest.pop(name, None) is not None:
                    log.info("peer %s is gone", name)

    def pose(self, peer: str, mine: list[BoxPose] | None = None) -> PeerPose | None:
        """Where ``peer`` stands in my frame, or None: unheard, stale, gone, or no shared box.
        ``mine``: my boxes now, when the caller has them already."""
        with self._lock:
            entry = self._latest.get(peer)
        if entry is None or self._clock() - entry[0] > self.settings.stale_after:
            return None
        mine = self._my_boxes() if mine is None else mine
        pose = peer_pose(mine, entry[1].boxes, entry[1].stamp)
        if pose is None or math.hypot(pose.x, pose.y) <= self.settings.arena:
            return pose
        with self._lock:  # counted once per message, however many frames ask
            judged, self._judged[peer] = self._judged.get(peer), entry[1]
        if judged is not entry[1]:
            distance = math.hypot(pose.x, pose.y)
            self._reject(peer, f"pose {distance:.4g} m away, beyond the arena")
        return None

    def poses(self, mine: list[BoxPose] | None = None) -> dict[str, PeerPose]:
        """Every peer that has a pose now (``mine`` as in :meth:`pose`)."""
        with self._lock:
            names = list(self._latest)
        if names and mine is None:
            mine = self._my_boxes()
        return {name: pose for name in names if (pose := self.pose(name, mine)) is not None}


class BoxPublisher:
    """Sends this robot's box poses ``box_rate`` times a second on a thread of its own.

    The schedule is monotonic (tick ``k`` is due at ``start + k / rate``), independent of the
    camera's frame rate; after a stall it skips the missed ticks instead of bursting.
    """

    def __init__(
        self,
        link: Link,
        robot: str,
        boxes: Callable[[], list[BoxPose]],
        rate: float = 5.0,
    ) -> None:
        self._link = link
        self._robot = robot
        self._boxes = boxes
        self._period = 1.0 / rate
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"boxes {robot}", daemon=True)
        self.sent = 0

    def start(self) -> BoxPublisher:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)

    def _run(self) -> None:
        due = time.monotonic()
        while not self._stop.is_set():
            try:
                message = Boxes(self._robot, time.time(), tuple(self._boxes()))
                self._link.publish("boxes", message)
                self.sent += 1
            except LinkError as err:
                log.warning("%s: box poses no longer sent: %s", self._robot, err)
                return
            except Exception:
                # A bad box list this tick must not end the exchange.
                log.exception("%s: publishing box poses failed", self._robot)
            due += self._period
            now = time.monotonic()
            if now - due > self._period:
                due = now
            self._stop.wait(max(0.0, due - now))
