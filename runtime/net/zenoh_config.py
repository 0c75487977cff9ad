"""Zenoh session configurations for the ways percept processes connect.

Pure builders: they return a :class:`zenoh.Config` and open nothing, so the messaging layer (and
anyone's script) decides when to open a session. The key names are Zenoh 1.x's (its
``DEFAULT_CONFIG.json5``).

- :func:`peer_config`: the default, robots talk directly over plain TCP on the endpoints their
  experiment gives them; multicast scouting is off so that two experiments on one network do not
  find each other.
- :func:`client_config`: the lab deployment, a robot or tool connects in client mode to the lab
  router over mutual TLS with the certificate directory ``percept certs`` made for it. Client mode
  matters: a peer whose certificate name does not match fails silently, a client gets an error.

:func:`bounded` caps what Zenoh puts together from the network (:data:`RX_MOST`): Zenoh
reassembles a large message from its fragments before any callback sees it, so a 50 MB payload
would cost 50 MB however soon it is refused after.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import zenoh

from percept.runtime.net.certs import CA_CERT, CERT, KEY, CertificateError
from percept.runtime.net.codec import JSON
from percept.runtime.net.messages import MAX_PAYLOAD

RX_MOST = 2 * MAX_PAYLOAD
"""Bytes of one Zenoh message received at most (twice a percept payload's bound, for the key
and headers): a larger one is dropped by Zenoh as its fragments come, never put together; the
link keeps going (Zenoh's own default is 1 GiB)."""


def bounded(settings: dict[str, JSON]) -> dict[str, JSON]:
    """``settings`` with Zenoh's received message size capped at :data:`RX_MOST`."""
    transport = settings.setdefault("transport", {})
    assert isinstance(transport, dict)
    link = transport.setdefault("link", {})
    assert isinstance(link, dict)
    link["rx"] = {"max_message_size": RX_MOST}
    return settings


def zenoh_problem(err: Exception) -> str:
    """A Zenoh error in words: Zenoh appends Rust source locations (" at /root/.cargo/...")."""
    return str(err).split(" at /", 1)[0]


def config(settings: Mapping[str, JSON]) -> zenoh.Config:
    """A :class:`zenoh.Config` from a dict of Zenoh's JSON5 configuration keys."""
    return zenoh.Config.from_json5(json.dumps(settings))


def peer_settings(listen: Sequence[str], connect: Sequence[str] = ()) -> dict[str, JSON]:
    """Peer mode on plain TCP: listen on ``listen``, connect to ``connect``, no multicast."""
    return {
        "mode": "peer",
        "listen": {"endpoints": list(listen)},
        "connect": {"endpoints": list(connect)},
        "scouting": {"multicast": {"enabled": False}},
    }


def client_settings(
    routers: Sequence[str], cert_dir: Path | None = None, *, connect_timeout: float | None = 0.0
) -> dict[str, JSON]:
    """Client mode over mutual TLS to ``routers`` with ``cert_dir``'s ca/cert/key.pem (plain
    TCP without ``cert_dir``: a researcher's script or a test connecting to a robot).

    ``connect_timeout`` is how long opening the session keeps trying, in seconds: 0 tries each
    router once, None tries until a router answers. Opening fails with :class:`zenoh.ZError`
    when no router accepts the robot (wrong CA, expired or missing certificate).
    """
    timeout_ms = -1 if connect_timeout is None else round(connect_timeout * 1000)
    settings: dict[str, JSON] = {
        "mode": "client",
        "connect": {"endpoints": list(routers), "timeout_ms": timeout_ms, "exit_on_failure": True},
        "scouting": {"multicast": {"enabled": False}},
    }
    if cert_dir is None:
        return settings
    files = {name: Path(cert_dir) / name for name in (CA_CERT, CERT, KEY)}
    missing = [str(path) for path in files.values() if not path.is_file()]
    if missing:
        raise CertificateError(f"missing certificate files: {', '.join(missing)}")
    settings["transport"] = {
        "link": {
            "tls": {
                "root_ca_certificate": str(files[CA_CERT].resolve()),
                "connect_certificate": str(files[CERT].resolve()),
                "connect_private_key": str(files[KEY].resolve()),
                # Without it the client sends no certificate and the router refuses it.
                "enable_mtls": True,
            }
        }
    }
    return settings


def peer_config(listen: Sequence[str], connect: Sequence[str] = ()) -> zenoh.Config:
    """:func:`peer_settings` as a :class:`zenoh.Config`."""
    return config(peer_settings(listen, connect))


def client_config(
    routers: Sequence[str], cert_dir: Path | None = None, *, connect_timeout: float | None = 0.0
) -> zenoh.Config:
    """:func:`client_settings` as a :class:`zenoh.Config`."""
    return config(client_settings(routers, cert_dir, connect_timeout=connect_timeout))
