"""One process's Zenoh session: publishing, validated receiving and peer liveliness (SPEC §4.8).

Keys are ``<prefix>/<name>/<topic>`` with the topics of :data:`percept.runtime.net.messages.TOPICS`,
and a liveliness token ``<prefix>/<name>/alive`` that disappears the moment the process (or its
session) ends. A token's name is checked like a message's sender (a bad one is rejected and
counted), and the names remembered are bounded (:data:`NAMES_KEPT`). One name is one process:
an ``exclusive`` link (the daemon's) refuses a name whose token is already on the network
(:class:`NameTaken`), and reports another holder that shows up later (:attr:`Link.clashes`,
through a second token ``<prefix>/<name>/alive/<session id>``: Zenoh merges equal tokens, so
the first one cannot tell two holders apart).

Three zenoh-python traps shape this class:

- callbacks run on Zenoh's threads, and one slow callback stalls the session: the callbacks here
  only copy the payload into a bounded queue (dropping the oldest when full, counted; an
  oversized payload is not even copied) and one thread of our own decodes, validates and hands
  messages to the handlers, counting per key what arrives and what is rejected
  (:meth:`Link.traffic`);
- a session with subscribers that is never closed keeps the process from exiting: :meth:`close`
  (also run at exit and by ``with``) closes it;
- a forked child must not use its parent's session: it gets a :class:`LinkError`.
"""

from __future__ import annotations

import atexit
import itertools
import json
import logging
import os
import re
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import zenoh

from percept.runtime.incidents import Run
from percept.runtime.net.certs import CertificateError
from percept.runtime.net.codec import JSON
from percept.runtime.net.mailbox import DropOldest
from percept.runtime.net.messages import (
    MAX_PAYLOAD,
    TOPICS,
    Message,
    MessageError,
    decode,
    encode,
    sender,
)
from percept.runtime.net.settings import NetworkSettings, name_problem
from percept.runtime.net.zenoh_config import (
    bounded,
    client_settings,
    config,
    peer_settings,
    zenoh_problem,
)

if TYPE_CHECKING:
    from percept.runtime.settings.experiment import Experiment

log = logging.getLogger("percept.link")

Handler = Callable[[Message], None]
AliveHandler = Callable[[str, bool], None]

_forked = False


def _after_fork_in_child() -> None:
    global _forked
    _forked = True


os.register_at_fork(after_in_child=_after_fork_in_child)


class LinkError(RuntimeError):
    """The Zenoh session cannot be opened or used."""


class NameTaken(LinkError):
    """Another process on the network already runs under this name (its liveliness token is
    there): two robots of one name would interleave their messages."""


@dataclass(frozen=True)
class Traffic:
    """What arrived on one key lately (:meth:`Link.traffic`): the sending robot (the key's
    robot segment) and topic, messages per second over the last second, and, in a run of
    rejections (no gap of :data:`QUIET` seconds), how many so far and the first one's reason."""

    robot: str
    topic: str
    rate: float
    rejected: int = 0
    reason: str | None = None


CLAIM_WAIT = 0.5  # seconds an exclusive link looks for another holder of its name before starting
QUIET = 2.0  # seconds without a message (or a rejection) that end a key's traffic (or run)
_KEYS_KEPT = 256  # keys whose traffic is remembered; idle ones are forgotten first
_ARRIVALS_KEPT = 4096  # arrival times per key: enough to measure rates far above any sane one
NAMES_KEPT = 256  # liveliness names remembered (:meth:`Link.alive`); gone ones are forgotten first
_WARNINGS_PER_10_S = 10  # log lines about rejected messages at most


@dataclass(frozen=True)
class _Arrival:
    """A sample handed from Zenoh's thread to the link's: its key and payload (its size when it
    was too large to copy); ``own``: one of this process's messages."""

    key: str
    payload: bytes | int
    own: bool = False


@dataclass(frozen=True)
class _AliveChange:
    """The liveliness token ``key`` appeared or went (its name not checked yet)."""

    key: str
    alive: bool


class _KeyTraffic:
    """Arrival times on one key, and the current run of rejections on it."""

    def __init__(self) -> None:
        self.arrivals: deque[float] = deque(maxlen=_ARRIVALS_KEPT)
        self.rejections = Run(QUIET)


def session_settings(
    settings: NetworkSettings, listen: list[str], robots: list[str]
) -> dict[str, JSON]:
    """Zenoh's configuration keys for a process listening on ``listen`` in an experiment whose
    other robots listen on ``robots``."""
    zenoh_settings: dict[str, JSON]
    if settings.mode == "client":
        if settings.certificates is not None:
            zenoh_settings = client_settings(settings.connect, settings.certificates)
        else:
            zenoh_settings = {"mode": "client", "connect": {"endpoints": list(settings.connect)}}
    else:
        zenoh_settings = peer_settings(listen, [*robots, *settings.connect])
        zenoh_settings["mode"] = settings.mode
    zenoh_settings["scouting"] = {"multicast": {"enabled": settings.multicast_scouting}}
    return bounded(zenoh_settings)


class Link:
    """The Zenoh session of robot (or program) ``name`` in an experiment.

    ``listen`` defaults to the robot's endpoint in the experiment (none for a program that is
    not a robot there); peers connect to every other robot's endpoint; ``exclusive``: see the
    module doc. Use as a context manager or call :meth:`close`.
    """

    def __init__(
        self,
        experiment: Experiment,
        name: str,
        settings: NetworkSettings | None = None,
        listen: list[str] | None = None,
        exclusive: bool = False,
    ) -> None:
        self.name = name
        self.prefix = experiment.prefix
        self.settings = settings or experiment.network
        if not re.fullmatch(r"[A-Za-z0-9_-]{1,64}", name):
            raise ValueError(f"name {name!r} may hold only letters, digits, - and _")
        robots = {r.name: r.endpoint for r in experiment.robots}
        self.listen = listen if listen is not None else [robots[name]] if name in robots else []
        if self.settings.mode == "client":
            self.listen = []  # a client only connects
        others = [endpoint for robot, endpoint in robots.items() if robot != name]
        try:
            zenoh_settings = session_settings(self.settings, self.listen, others)
        except CertificateError as err:
            raise LinkError(f"{name}: {err}") from None
        self.rejected = 0
        self.rejected_by_key: Counter[str] = Counter()
        self._handlers: list[tuple[str, Handler, bool]] = []
        self._alive_handlers: list[AliveHandler] = []
        self._alive: dict[str, bool] = {}
        self._lock = threading.Lock()
        # Zenoh callbacks only hand samples over; one slow callback would stall the session.
        self._queue: DropOldest[_Arrival | _AliveChange | None] = DropOldest(self.settings.queue)
        self._traffic: dict[str, _KeyTraffic] = {}
        self._traffic_lock = threading.Lock()
        self._warnings: deque[float] = deque(maxlen=_WARNINGS_PER_10_S)
        self._closed = False
        try:
            self.session = zenoh.open(config(zenoh_settings))
        except zenoh.ZError as err:
            raise LinkError(f"{name}: cannot open a Zenoh session: {zenoh_problem(err)}") from None
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._subscribers: list[zenoh.Subscriber[None]] = []
        self._clashes: set[str] = set()
        if exclusive:
            self._claim()
        atexit.register(self.close)
        connect = _endpoints(zenoh_settings)
        log.info(
            "%s: Zenoh %s session, listening on %s, connecting to %s, multicast scouting %s",
            name,
            zenoh_settings["mode"],
            ", ".join(self.listen) or "-",
            ", ".join(connect) or "-",
            "on" if self.settings.multicast_scouting else "off",
        )
        self._token = self.session.liveliness().declare_token(self.key(name, "alive"))
        self._thread = threading.Thread(target=self._dispatch, name=f"link {name}", daemon=True)
        self._thread.start()

    def _claim(self) -> None:
        """Refuse this name if another process holds its token now; otherwise mark this session
        as the name's holder (a token ``<prefix>/<name>/alive/<session id>``) and watch for
        other holders that appear later (:attr:`clashes`)."""
        key = self.key(self.name, "alive")
        if self._held(key):
            self.session.close()
            raise NameTaken(
                f"another process already runs as {self.name!r} on this network (its "
                f"liveliness token {key} is there); stop it or give this one another name"
            )
        self._me = str(self.session.info.zid())
        liveliness = self.session.liveliness()
        self._instance = liveliness.declare_token(f"{key}/{self._me}")
        self._subscribers.append(
            liveliness.declare_subscriber(f"{key}/*", self._on_holder, history=True)
        )

    def _held(self, key: str) -> bool:
        """Whether a token ``key`` shows up within :data:`CLAIM_WAIT` seconds: a query answers at
        once from the peers met so far, and a peer's peers are met (gossip) within about 60 ms."""
        deadline = time.monotonic() + CLAIM_WAIT
        while True:
            replies = self.session.liveliness().get(key, timeout=CLAIM_WAIT)
            if any(reply.ok is not None for reply in replies):
                return True
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)

    def _on_holder(self, sample: zenoh.Sample) -> None:
        holder = str(sample.key_expr).rsplit("/", 1)[-1]
        if holder == self._me:
            return
        with self._lock:
            if sample.kind == zenoh.SampleKind.PUT:
                self._clashes.add(holder)
            else:
                self._clashes.discard(holder)
        log.warning(
            "%s: another process (Zenoh session %s) %s as %r",
            self.name,
            holder,
            "runs" if sample.kind == zenoh.SampleKind.PUT else "no longer runs",
            self.name,
        )

    @property
    def clashes(self) -> list[str]:
        """The other sessions (Zenoh ids) running under this name now (an ``exclusive`` link
        only): they appeared after this one started, e.g. when two networks were joined."""
        with self._lock:
            return sorted(self._clashes)

    def key(self, robot: str, topic: str) -> str:
        """``<prefix>/<robot>/<topic>``."""
        return f"{self.prefix}/{robot}/{topic}"

    def __enter__(self) -> Link:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def _usable(self) -> None:
        if _forked:
            raise LinkError("this process was forked after its Zenoh session was opened")
        if self._closed:
            raise LinkError(f"{self.name}: the link is closed")

    # -- sending ----------------------------------------------------------------------------------

    def publish(self, topic: str, message: Message | Mapping[str, JSON]) -> None:
        """Send ``message`` on ``<prefix>/<name>/<topic>``. A mapping is checked against the
        topic's schema first, so nothing this process sends is rejected by its peers."""
        self._usable()
        if topic not in TOPICS:
            raise ValueError(f"unknown topic {topic!r}; known: {', '.join(TOPICS)}")
        if isinstance(message, Mapping):
            payload = encode(decode(_json({"schema": TOPICS[topic], **message}), TOPICS[topic]))
        else:
            if TOPICS[topic] != message.SCHEMA:
                raise MessageError(f"a {message.SCHEMA} message does not go on /{topic}")
            payload = encode(message)
        self.send(topic, payload)

    def send(self, topic: str, payload: bytes) -> None:
        """Send an encoded message (:func:`~percept.runtime.net.messages.encode`) of this
        process's on ``<prefix>/<name>/<topic>``: for a caller that checked it by encoding it."""
        self._usable()
        if topic not in TOPICS:
            raise ValueError(f"unknown topic {topic!r}; known: {', '.join(TOPICS)}")
        self._publisher(topic).put(payload)

    def listened(self, topic: str) -> bool:
        """Whether any process subscribes to this process's ``topic`` now (Zenoh's matching
        status): e.g. wait for it before a message that must not go unheard."""
        self._usable()
        if topic not in TOPICS:
            raise ValueError(f"unknown topic {topic!r}; known: {', '.join(TOPICS)}")
        # A zenoh.MatchingStatus: zenoh's own stub (1.10) calls it a bool.
        return bool(self._publisher(topic).matching_status.matching)  # type: ignore[attr-defined]

    def _publisher(self, topic: str) -> zenoh.Publisher:
        with self._lock:
            publisher = self._publishers.get(topic)
            if publisher is None:
                publisher = self.session.declare_publisher(
                    self.key(self.name, topic), encoding=zenoh.Encoding.APPLICATION_JSON
                )
                self._publishers[topic] = publisher
            return publisher

    # -- receiving --------------------------------------------------------------------------------

    def subscribe(self, topic: str, handler: Handler, *, own: bool = False) -> None:
        """Call ``handler(message)`` on this link's thread for every valid message on
        ``<prefix>/*/<topic>``; by default not for this process's own messages."""
        self._usable()
        if topic not in TOPICS:
            raise ValueError(f"unknown topic {topic!r}; known: {', '.join(TOPICS)}")
        with self._lock:
            first = not any(t == topic for t, _, _ in self._handlers)
            first_own = own and not any(t == topic and o for t, _, o in self._handlers)
            self._handlers.append((topic, handler, own))
        # Other processes' messages and this one's come through separate subscribers: only
        # the others' are traffic (rates, floods), and a message on this process's key from
        # elsewhere is then told apart from its own.
        if first:
            self._subscribers.append(
                self.session.declare_subscriber(
                    self.key("*", topic), self._on_sample, allowed_origin=zenoh.Locality.REMOTE
                )
            )
        if first_own:
            self._subscribers.append(
                self.session.declare_subscriber(
                    self.key(self.name, topic),
                    self._on_own_sample,
                    allowed_origin=zenoh.Locality.SESSION_LOCAL,
                )
            )

    def watch_alive(self, handler: AliveHandler) -> None:
        """Call ``handler(name, alive)`` when a process's liveliness token appears or goes; the
        tokens present now are reported at once."""
        self._usable()
        with self._lock:
            first = not self._alive_handlers
            self._alive_handlers.append(handler)
        if first:
            self._subscribers.append(
                self.session.liveliness().declare_subscriber(
                    self.key("*", "alive"), self._on_alive, history=True
                )
            )

    def alive(self, name: str) -> bool | None:
        """Whether ``name``'s token is present (None: never seen; needs :meth:`watch_alive`)."""
        with self._lock:
            return self._alive.get(name)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        size = len(sample.payload)
        if size > MAX_PAYLOAD:  # refused without copying it: a flood of these costs no memory
            self._queue.put(_Arrival(str(sample.key_expr), size))
        else:
            self._queue.put(_Arrival(str(sample.key_expr), sample.payload.to_bytes()))

    def _on_own_sample(self, sample: zenoh.Sample) -> None:
        self._queue.put(_Arrival(str(sample.key_expr), sample.payload.to_bytes(), own=True))

    def _on_alive(self, sample: zenoh.Sample) -> None:
        # Checked on the link's thread, as messages are: a made-up name is counted there.
        self._queue.put(_AliveChange(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))

    def _alive_changed(self, change: _AliveChange) -> None:
        """A token came or went: a valid name is remembered (bounded: see :meth:`_remember`)
        and handed to the handlers; any other is rejected and counted like a bad message."""
        name = self._name_in(change.key)
        if name is None:
            return
        problem = name_problem(name)
        if problem is not None:
            self._reject(change.key, MessageError(f"liveliness token of a bad name: {problem}"))
            return
        self._remember(name, change.alive)
        for handler in list(self._alive_handlers):
            handler(name, change.alive)

    def _remember(self, name: str, alive: bool) -> None:
        """Keep ``name``'s liveliness for :meth:`alive`: at most :data:`NAMES_KEPT` names, the
        longest gone forgotten first, then the longest known (a stranger making up names at
        any rate costs a bounded table)."""
        with self._lock:
            self._alive.pop(name, None)
            if len(self._alive) >= NAMES_KEPT:
                gone = next((n for n, up in self._alive.items() if not up), None)
                del self._alive[gone if gone is not None else next(iter(self._alive))]
            self._alive[name] = alive

    @property
    def dropped(self) -> int:
        """Samples dropped because our thread fell behind Zenoh's."""
        return self._queue.dropped

    def _name_in(self, key: str) -> str | None:
        """The robot segment of ``<prefix>/<robot>/<topic>``."""
        rest = key.removeprefix(self.prefix + "/")
        parts = rest.split("/")
        return parts[0] if rest != key and len(parts) == 2 else None

    def _dispatch(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            try:
                if isinstance(item, _AliveChange):
                    self._alive_changed(item)
                else:
                    self._deliver(item.key, item.payload, own=item.own)
            except Exception:
                # A handler's bug must not end the link's thread.
                log.exception("%s: handler failed on %s", self.name, _what(item))

    def _deliver(self, key: str, payload: bytes | int, own: bool = False) -> None:
        """Decode, check and hand on a message from another process (``own``: from this one,
        for the handlers that asked for those)."""
        topic = key.rsplit("/", 1)[-1]
        robot = self._name_in(key)
        if not own:
            self._arrived(key)
        try:
            if isinstance(payload, int):
                raise MessageError(f"payload of {payload} bytes, more than {MAX_PAYLOAD}")
            message = decode(payload, TOPICS.get(topic))
            if robot != sender(message):
                raise MessageError(f"sent by {sender(message)!r} on {robot!r}'s key")
        except MessageError as err:
            self._reject(key, err)
            return
        with self._lock:
            handlers = [
                h
                for t, h, wants_own in self._handlers
                if t == topic and (wants_own if own else wants_own or robot != self.name)
            ]
        for handler in handlers:
            handler(message)

    def _arrived(self, key: str) -> None:
        now = time.monotonic()
        with self._traffic_lock:
            entry = self._traffic.get(key)
            if entry is None:
                if len(self._traffic) >= _KEYS_KEPT:
                    self._forget_idle()
                entry = self._traffic[key] = _KeyTraffic()
            arrivals = entry.arrivals
            arrivals.append(now)
            # Only the last second makes the rate: a steady sender costs its rate, not the bound.
            while arrivals[0] < now - 1.0:
                arrivals.popleft()

    def _forget_idle(self) -> None:
        """Drop the keys that were quiet longest (the table stays bounded, whatever the keys)."""
        by_age = sorted(self._traffic, key=lambda k: self._traffic[k].arrivals[-1])
        for key in by_age[: max(1, len(by_age) // 4)]:
            del self._traffic[key]

    def traffic(self) -> dict[str, Traffic]:
        """Per key heard from in the last :data:`QUIET` seconds: its message rate over the last
        second, and its current run of rejections, if any."""
        now = time.monotonic()
        out: dict[str, Traffic] = {}
        with self._traffic_lock:
            for key, entry in self._traffic.items():
                if not entry.arrivals or now - entry.arrivals[-1] > QUIET:
                    continue
                recent = sum(
                    1
                    for _ in itertools.takewhile(lambda t: t > now - 1.0, reversed(entry.arrivals))
                )
                run = entry.rejections
                rejecting = run.active(now)
                out[key] = Traffic(
                    robot=self._name_in(key) or "",
                    topic=key.rsplit("/", 1)[-1],
                    rate=float(recent),
                    rejected=run.count if rejecting else 0,
                    reason=run.reason if rejecting else None,
                )
        return out

    def _reject(self, key: str, err: MessageError) -> None:
        self.rejected += 1
        if key not in self.rejected_by_key and len(self.rejected_by_key) >= _KEYS_KEPT:
            # bounded whatever keys a babbler makes up: keep the worst offenders
            self.rejected_by_key = Counter(dict(self.rejected_by_key.most_common(_KEYS_KEPT // 2)))
        self.rejected_by_key[key] += 1
        now = time.monotonic()
        with self._traffic_lock:
            entry = self._traffic.get(key)
            if entry is not None:
                entry.rejections.add(str(err), now)
        # The first rejection on a key, then at most one line every 10 s, and never more than
        # a few lines in 10 s: a babbling sender, even one making up keys, must not flood the log.
        recent = [t for t in self._warnings if now - t < 10.0]
        first = self.rejected_by_key[key] == 1 and len(recent) < _WARNINGS_PER_10_S
        if first or not recent:
            self._warnings.append(now)
            log.warning("%s: rejected message %d on %s: %s", self.name, self.rejected, key, err)

    # -- ending -----------------------------------------------------------------------------------

    def close(self) -> None:
        """Withdraw the liveliness token, close the session and stop the thread. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        atexit.unregister(self.close)
        if not _forked:
            self.session.close()
        self._queue.put(None)
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)
        log.info(
            "%s: Zenoh session closed (%d rejected, %d dropped)",
            self.name,
            self.rejected,
            self.dropped,
        )


def _what(item: _Arrival | _AliveChange) -> str:
    """What a handler failed on, for the log: ``alive``, ``own`` or the key."""
    if isinstance(item, _AliveChange):
        return item.key
    return "own" if item.own else item.key


def _endpoints(zenoh_settings: Mapping[str, JSON]) -> list[str]:
    """The endpoints a Zenoh configuration connects to (``connect.endpoints``)."""
    connect = zenoh_settings.get("connect")
    endpoints = connect.get("endpoints") if isinstance(connect, dict) else None
    return [str(e) for e in endpoints] if isinstance(endpoints, list) else []


def _json(body: Mapping[str, JSON]) -> bytes:
    try:
        return json.dumps(body, allow_nan=False).encode()
    except (TypeError, ValueError) as err:
        raise MessageError(f"cannot encode: {err}") from None
