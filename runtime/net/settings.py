"""Settings of an experiment's networking, light enough for config loading: the ``[network]``
table (how the processes meet on Zenoh) and the ``[peers]`` table (box exchange, peer poses,
pointing and joint attention)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from percept.config.loader import FieldError

ROBOT_NAME = re.compile(r"[A-Za-z0-9_-]{1,64}")
"""A robot's (or program's) name: one Zenoh key-expression chunk, as every message's ``robot``
field, certificate and experiment entry has it (matched whole: ``fullmatch``)."""


def name_problem(name: str) -> str | None:
    """Why ``name`` cannot name a robot, or None."""
    if not ROBOT_NAME.fullmatch(name):
        return f"{name!r}: expected 1 to 64 letters, digits, - and _"
    return None


_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream", "unixpipe", "serial", "vsock")
_PORTED = ("tcp", "udp", "tls", "quic", "ws")


def endpoint_problem(endpoint: str) -> str | None:
    """Why ``endpoint`` is not a Zenoh endpoint ``PROTOCOL/ADDRESS`` (``tcp/HOST:PORT``, port
    0-65535), or None; Zenoh itself would only say so when the session opens."""
    locator = re.split(r"[?#]", endpoint, maxsplit=1)[0]
    protocol, _, address = locator.partition("/")
    if protocol not in _PROTOCOLS or not address:
        return (
            f"expected PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447, with a protocol of "
            f"{', '.join(_PROTOCOLS)}; got {endpoint!r}"
        )
    if protocol in _PORTED:
        host, colon, port = address.rpartition(":")
        if not (colon and host and port.isdigit() and int(port) <= 65535):
            return f"expected {protocol}/HOST:PORT with a port 0-65535, got {endpoint!r}"
    return None


def prefix_problem(prefix: str) -> str | None:
    """Why ``prefix`` cannot begin every key of an experiment, or None: a Zenoh key is non-empty
    chunks joined by ``/``; ``*`` and ``$`` would make it a pattern, ``?`` and ``#`` are
    forbidden."""
    if any(not chunk for chunk in prefix.split("/")):
        return f"expected non-empty parts joined by /, got {prefix!r}"
    bad = sorted(set(prefix) & set("*$?#"))
    if bad:
        return f"{prefix!r} holds {' '.join(bad)}: a key may not hold * $ ? or #"
    return None


@dataclass(frozen=True)
class NetworkSettings:
    """The experiment's ``[network]`` table: how the processes of an experiment meet.

    ``peer`` (default): each robot listens on its experiment endpoint and connects to the other
    robots' endpoints (and to ``connect``). ``client``: connect to the routers in ``connect``
    only (over mutual TLS with ``certificates``, the directory ``percept certs`` made).
    ``router``: like peer, but the process also routes for clients connected to it.
    """

    mode: Literal["peer", "client", "router"] = field(
        default="peer", metadata={"doc": "Zenoh mode: peer, client or router"}
    )
    connect: tuple[str, ...] = field(
        default=(), metadata={"doc": "more endpoints to connect to (client: the routers)"}
    )
    multicast_scouting: bool = field(
        default=False, metadata={"doc": "find peers by UDP multicast (off: explicit endpoints)"}
    )
    certificates: Path | None = field(
        default=None, metadata={"doc": "client mode over TLS: certificate directory"}
    )
    queue: int = field(
        default=256,
        metadata={"min": 1, "max": 100000, "doc": "received messages waiting to be handled"},
    )

    @property
    def lab(self) -> bool:
        """Whether this is the lab deployment: client mode over mutual TLS, where the router
        lets each party publish only under its certificate's name."""
        return self.mode == "client" and self.certificates is not None

    def trust(self, listen: list[str]) -> str:
        """Who can speak as a player to a process listening on ``listen``, in words."""
        if self.lab:
            return "lab: mutual TLS, each process publishes only under its certificate's name"
        reach = ", ".join(self.connect) if self.mode == "client" else ", ".join(listen) or "-"
        return (
            f"{self.mode} mode: any process that reaches {reach} can speak as a player "
            "(the lab deployment, client mode over mutual TLS, can tell them apart)"
        )

    def __post_init__(self) -> None:
        for i, endpoint in enumerate(self.connect):
            problem = endpoint_problem(endpoint)
            if problem:
                raise FieldError(f"connect[{i}]", problem)
        if self.mode == "client" and not self.connect:
            raise ValueError("client mode needs the routers' endpoints in connect")


@dataclass(frozen=True)
class PeerSettings:
    """The experiment's ``[peers]`` table: box exchange, peer poses, pointing, joint attention
    and the games the monitor starts."""

    box_rate: float = field(
        default=5.0, metadata={"min": 0.1, "max": 100.0, "doc": "box messages per second"}
    )
    stale_after: float = field(
        default=1.0,
        metadata={
            "min": 0.05,
            "max": 86400.0,
            "doc": "seconds without a peer's boxes before it has no pose",
        },
    )
    pointing_gate: float = field(
        default=0.05,
        metadata={
            "min": 0.0,
            "max": 100.0,
            "doc": "metres: pointing finds the nearest object within this, or within twice "
            "this when no other object is within twice its distance, else none (keep it below "
            "half the objects' spacing, or a neighbour can pass for the topic)",
        },
    )
    attention_gate: float = field(
        default=0.05,
        metadata={
            "min": 0.0,
            "max": 100.0,
            "doc": "metres: joint attention pairs objects closer than this (below half their "
            "spacing too)",
        },
    )
    attention: Literal["shared", "same"] = field(
        default="shared",
        metadata={
            "doc": "when two robots attend jointly: they share a context, at least "
            "attention_least objects both see matched through the peer pose (shared), or they "
            "see exactly the same set of objects (same, the chapter's rule)"
        },
    )
    attention_least: int = field(
        default=2,
        metadata={"min": 1, "max": 1000, "doc": "objects a shared context holds at least"},
    )
    games: tuple[Literal["pointing", "guessing"], ...] = field(
        default=("pointing", "guessing"),
        metadata={"doc": "the games the monitor starts for two robots attending jointly"},
    )
    game_interval: float = field(
        default=2.0,
        metadata={
            "min": 0.05,
            "max": 86400.0,
            "doc": "seconds between the games the monitor starts while two robots attend jointly",
        },
    )
    answer_timeout: float = field(
        default=2.0,
        metadata={"min": 0.01, "max": 86400.0, "doc": "seconds a speaker waits for an answer"},
    )
    arena: float = field(
        default=20.0,
        metadata={
            "min": 0.1,
            "max": 1000.0,
            "doc": "metres: the farthest two things of the experiment (robots, boxes) can be "
            "apart; a peer's box or pose farther from the robot is implausible, rejected and "
            "reported by sender",
        },
    )
    players: tuple[str, ...] = field(
        default=(),
        metadata={
            "doc": "robots the daemons play games with (empty: the experiment's robots); "
            "requests, verdicts, words and start signals from or about others are ignored"
        },
    )
    monitor: str = field(
        default="monitor",
        metadata={
            "doc": "the name the joint-attention monitor runs under (percept monitor --name): "
            "a start signal is heeded from it or from a player, from no one else"
        },
    )
    network_gaze: Literal["any", "lab"] = field(
        default="any",
        metadata={
            "doc": "where games from the network may turn the head: in any deployment (any), "
            "or only in the lab's, client mode over mutual TLS (lab: elsewhere the games are "
            "played without looking)"
        },
    )

    def __post_init__(self) -> None:
        problem = name_problem(self.monitor)
        if problem:
            raise FieldError("monitor", problem)
