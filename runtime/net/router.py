"""The lab router: one Zenoh router that every robot reaches, with mutual TLS and access control.

In a lab with many robots on one network, each robot connects in client mode to this router
(:func:`percept.runtime.net.zenoh_config.client_config`). The router accepts only links whose client
certificate was signed by the lab CA, and its access control lets each party publish only under
its own name, ``<prefix>/<name>/**``, where the name is its certificate's common name, so robot a
cannot speak for robot b. Everyone with a lab certificate may subscribe to and query
``<prefix>/**``. Other programs (a joint-attention monitor, a game script) can be granted more
keys by name.

The router file (TOML)::

    listen = ["tls/0.0.0.0:7447"]     # TLS endpoints only
    ca = "certs/router/ca.pem"         # the lab CA; paths relative to this file
    certificate = "certs/router/cert.pem"
    private_key = "certs/router/key.pem"
    prefix = "percept"
    robots = ["a", "b", "c"]           # certificate common names

    [[clients]]                        # optional: more publishing rights for a named program
    name = "monitor"
    publish = ["games/**"]             # key expressions under the prefix
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

from percept.config.loader import ConfigError, load
from percept.runtime.net.certs import (
    CertificateError,
    check_certificate,
    check_private_key,
)
from percept.runtime.net.codec import JSON
from percept.runtime.net.settings import endpoint_problem, name_problem, prefix_problem
from percept.runtime.net.zenoh_config import bounded, config, zenoh_problem

log = logging.getLogger("percept.router")

# What a party may send into the router under its own keys, what anyone may ask of it, and what
# the router may pass on (everything under the prefix: the ingress rules already decided).
_WRITE = ("put", "delete", "declare_queryable", "reply", "liveliness_token")
_READ = ("declare_subscriber", "query", "declare_liveliness_subscriber", "liveliness_query")
_DELIVER = _WRITE + _READ


@dataclass(frozen=True)
class ClientGrant:
    """A program other than a robot that may publish on more keys than its own."""

    name: str = field(metadata={"doc": "its certificate's common name"})
    publish: tuple[str, ...] = field(
        default=(), metadata={"doc": "more key expressions it may publish on, under the prefix"}
    )


@dataclass(frozen=True)
class RouterSettings:
    """The lab router: where it listens, its certificates and who may publish what."""

    ca: Path = field(metadata={"doc": "the lab CA certificate (PEM) that signed every client"})
    certificate: Path = field(metadata={"doc": "the router's certificate (PEM)"})
    private_key: Path = field(metadata={"doc": "the router's private key (PEM)"})
    robots: tuple[str, ...] = field(metadata={"doc": "robot names (certificate common names)"})
    listen: tuple[str, ...] = field(
        default=("tls/0.0.0.0:7447",), metadata={"doc": "TLS endpoints to listen on"}
    )
    prefix: str = field(default="percept", metadata={"doc": "first part of every Zenoh key"})
    clients: tuple[ClientGrant, ...] = field(
        default=(), metadata={"doc": "other programs granted more keys to publish on"}
    )


def _key_expr_problem(expr: str) -> str | None:
    try:
        zenoh.KeyExpr(expr)
    except zenoh.ZError as err:
        return zenoh_problem(err)
    return None


def _check(settings: RouterSettings, file: Path) -> None:
    """The rules a dataclass cannot state per field, each reported at its exact key."""
    for i, endpoint in enumerate(settings.listen):
        if not endpoint.startswith("tls/"):
            raise ConfigError(file, f"listen[{i}]", f"expected a tls/ endpoint, got {endpoint!r}")
        problem = endpoint_problem(endpoint)
        if problem:
            raise ConfigError(file, f"listen[{i}]", problem)
    if not settings.listen:
        raise ConfigError(file, "listen", "expected at least one tls/ endpoint")
    checks = (
        ("ca", check_certificate),
        ("certificate", check_certificate),
        ("private_key", check_private_key),
    )
    for key, check in checks:
        try:
            check(getattr(settings, key))
        except CertificateError as err:
            raise ConfigError(file, key, str(err)) from None
    problem = prefix_problem(settings.prefix)
    if problem:
        raise ConfigError(file, "prefix", problem)
    if not settings.robots:
        raise ConfigError(file, "robots", "expected at least one robot name")
    names = [(f"robots[{i}]", n) for i, n in enumerate(settings.robots)]
    names += [(f"clients[{i}].name", c.name) for i, c in enumerate(settings.clients)]
    seen: set[str] = set()
    for key, name in names:
        problem = name_problem(name)
        if problem:
            raise ConfigError(file, key, problem)
        if name in seen:
            raise ConfigError(file, key, f"{name!r} is named twice")
        seen.add(name)
    for i, client in enumerate(settings.clients):
        for j, expr in enumerate(client.publish):
            problem = _key_expr_problem(f"{settings.prefix}/{expr}")
            if problem:
                raise ConfigError(file, f"clients[{i}].publish[{j}]", problem)


def load_router_settings(path: str | Path) -> RouterSettings:
    """Read and check a router file; raises :class:`percept.config.loader.ConfigError`."""
    settings = load(RouterSettings, path)
    _check(settings, Path(path))
    return settings


def access_control(settings: RouterSettings) -> dict[str, JSON]:
    """Zenoh's ``access_control`` section: deny by default, then grant by certificate name."""
    everything = f"{settings.prefix}/**"
    grants = {name: [f"{settings.prefix}/{name}/**"] for name in settings.robots}
    for client in settings.clients:
        grants[client.name] = [f"{settings.prefix}/{client.name}/**"] + [
            f"{settings.prefix}/{expr}" for expr in client.publish
        ]
    rules: list[JSON] = [
        _rule("read", _READ, "ingress", [everything]),
        _rule("deliver", _DELIVER, "egress", [everything]),
    ]
    # Ids hold a space, which names cannot: a robot called "read" or "lab" cannot clash with them.
    subjects: list[JSON] = [{"id": "any lab certificate"}]  # no property: a wildcard
    policies: list[JSON] = [{"rules": ["read", "deliver"], "subjects": ["any lab certificate"]}]
    for name, exprs in grants.items():
        rules.append(_rule(f"write {name}", _WRITE, "ingress", exprs))
        subjects.append({"id": f"cn {name}", "cert_common_names": [name]})
        policies.append({"rules": [f"write {name}"], "subjects": [f"cn {name}"]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def _rule(rule_id: str, messages: tuple[str, ...], flow: str, exprs: list[str]) -> JSON:
    return {
        "id": rule_id,
        "messages": list(messages),
        "flows": [flow],
        "permission": "allow",
        "key_exprs": list(exprs),
    }


def router_settings(settings: RouterSettings) -> dict[str, JSON]:
    """The router's whole Zenoh configuration (JSON5 keys of Zenoh 1.x)."""
    return bounded(
        {
            "mode": "router",
            "listen": {"endpoints": list(settings.listen)},
            "scouting": {"multicast": {"enabled": False}},
            "transport": {
                "link": {
                    "protocols": ["tls"],
                    "tls": {
                        "root_ca_certificate": str(settings.ca),
                        "listen_certificate": str(settings.certificate),
                        "listen_private_key": str(settings.private_key),
                        "enable_mtls": True,
                        "close_link_on_expiration": True,
                    },
                }
            },
            "access_control": access_control(settings),
        }
    )


class RouterError(Exception):
    """Zenoh could not start the router (port in use, certificate refused, ...)."""


def serve(settings: RouterSettings, stop: threading.Event) -> None:
    """Run the router until ``stop`` is set, then close it."""
    try:
        session = zenoh.open(config(router_settings(settings)))
    except zenoh.ZError as err:
        raise RouterError(f"cannot start the router: {zenoh_problem(err)}") from None
    try:
        links = session.info.declare_link_events_listener(_log_link)
        log.info(
            "router %s listening on %s for robots %s, prefix %s",
            session.info.zid(),
            ", ".join(settings.listen),
            ", ".join(settings.robots),
            settings.prefix,
        )
        stop.wait()
        links.undeclare()
    finally:
        session.close()
        log.info("router closed")


def _log_link(event: zenoh.LinkEvent) -> None:
    # Runs on a Zenoh thread: log and return at once.
    link = event.link
    what = "connected" if event.kind == zenoh.SampleKind.PUT else "disconnected"
    log.info("%s %s from %s (zid %s)", link.auth_identifier or "?", what, link.dst, link.zid)
