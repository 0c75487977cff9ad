"""The lab's certificate authority and the certificates of its router, robots and tools.

A lab deployment (see :mod:`percept.runtime.net.router`) authenticates every Zenoh link with mutual
TLS: the router proves it is the lab's router, each robot proves which robot it is. The robot's name
is the common name (CN) of its client certificate, and the router's access control grants by that
name. :func:`make_lab_certificates` writes one directory per party::

    OUT/ca.pem  OUT/ca.key            the lab CA (keep ca.key off the robots)
    OUT/router/{ca,cert,key}.pem      the router's server certificate, SAN = the router's hosts
    OUT/<name>/{ca,cert,key}.pem      one client certificate per robot or tool, CN = <name>

Each party's directory is what gets copied to that machine. Running it again with an existing
``OUT/ca.pem`` and ``OUT/ca.key`` reuses that CA, so robots can be added to a running lab.
"""

from __future__ import annotations

import datetime
import ipaddress
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from percept.runtime.net.settings import name_problem

if TYPE_CHECKING:
    from cryptography import x509
    from cryptography.hazmat.primitives.asymmetric import ec

# cryptography is imported where certificates are made or read, not at the top: a daemon that
# only names CertificateError (every daemon's link does) starts 0.1 s of CPU sooner without it.

log = logging.getLogger("percept.certs")

CA_CERT, CA_KEY = "ca.pem", "ca.key"
CERT, KEY = "cert.pem", "key.pem"
ROUTER_DIR = "router"


class CertificateError(Exception):
    """The certificates cannot be made as asked (bad name, unreadable CA, ...)."""


@dataclass(frozen=True)
class Issuer:
    """A certificate authority able to sign: its certificate and private key."""

    certificate: x509.Certificate
    key: ec.EllipticCurvePrivateKey


def _new_key() -> ec.EllipticCurvePrivateKey:
    from cryptography.hazmat.primitives.asymmetric import ec

    return ec.generate_private_key(ec.SECP256R1())


def _write_key(path: Path, key: ec.EllipticCurvePrivateKey) -> None:
    from cryptography.hazmat.primitives import serialization

    pem = key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )
    # Created 0600 from the start: a private key must never be readable by others, not even briefly.
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as fh:
        fh.write(pem)


def _write_cert(path: Path, cert: x509.Certificate) -> None:
    from cryptography.hazmat.primitives import serialization

    path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))


def _validity(days: int) -> tuple[datetime.datetime, datetime.datetime]:
    # Back-dated an hour so that a robot whose clock lags a little still accepts the certificates.
    now = datetime.datetime.now(datetime.UTC)
    return now - datetime.timedelta(hours=1), now + datetime.timedelta(days=days)


def make_ca(name: str, days: int) -> Issuer:
    """A new self-signed certificate authority called ``name``, valid for ``days``."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.x509.oid import NameOID

    key = _new_key()
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    start, end = _validity(days)
    cert = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(end)
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=False,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return Issuer(cert, key)


def _host_name(host: str) -> x509.GeneralName:
    from cryptography import x509

    try:
        return x509.IPAddress(ipaddress.ip_address(host))
    except ValueError:
        return x509.DNSName(host)


def issue(
    issuer: Issuer, common_name: str, days: int, *, hosts: Sequence[str] = ()
) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    """A certificate for ``common_name`` signed by ``issuer``, and its new private key.

    With ``hosts`` it is a server certificate for those IP addresses and DNS names (the names a
    client checks when it connects); without, a client certificate.
    """
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    key = _new_key()
    start, end = _validity(days)
    usage = ExtendedKeyUsageOID.SERVER_AUTH if hosts else ExtendedKeyUsageOID.CLIENT_AUTH
    builder = (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)]))
        .issuer_name(issuer.certificate.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(end)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=False,
                crl_sign=False,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(issuer.key.public_key()),
            critical=False,
        )
    )
    if hosts:
        builder = builder.add_extension(
            x509.SubjectAlternativeName([_host_name(h) for h in hosts]), critical=False
        )
    return builder.sign(issuer.key, hashes.SHA256()), key


def _read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise CertificateError(f"file not found: {path}") from None
    except OSError as err:
        raise CertificateError(f"cannot read {path}: {err.strerror}") from None


def check_certificate(path: Path) -> None:
    """Raise :class:`CertificateError` unless ``path`` holds a PEM certificate."""
    from cryptography import x509

    try:
        x509.load_pem_x509_certificate(_read(path))
    except ValueError:
        raise CertificateError(f"{path} holds no PEM certificate") from None


def check_private_key(path: Path) -> None:
    """Raise :class:`CertificateError` unless ``path`` holds an unencrypted PEM private key."""
    from cryptography.hazmat.primitives import serialization

    try:
        serialization.load_pem_private_key(_read(path), None)
    except (ValueError, TypeError):
        raise CertificateError(f"{path} holds no unencrypted PEM private key") from None


def load_ca(directory: Path) -> Issuer:
    """The CA kept in ``directory`` (``ca.pem`` and ``ca.key``)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric import ec

    try:
        cert = x509.load_pem_x509_certificate((directory / CA_CERT).read_bytes())
        key = serialization.load_pem_private_key((directory / CA_KEY).read_bytes(), None)
    except (OSError, ValueError, TypeError) as err:
        raise CertificateError(f"cannot read the CA in {directory}: {err}") from None
    if not isinstance(key, ec.EllipticCurvePrivateKey):
        raise CertificateError(f"{directory / CA_KEY}: expected an EC private key")
    return Issuer(cert, key)


def _write_party(out: Path, issuer: Issuer, name: str, days: int, hosts: Sequence[str]) -> Path:
    directory = out / name
    directory.mkdir(parents=True, exist_ok=True)
    cert, key = issue(issuer, name, days, hosts=hosts)
    _write_cert(directory / CA_CERT, issuer.certificate)
    _write_cert(directory / CERT, cert)
    _write_key(directory / KEY, key)
    return directory


def make_lab_certificates(
    out: Path,
    names: Sequence[str],
    *,
    ca_name: str = "percept lab CA",
    days: int = 825,
    hosts: Sequence[str] = ("127.0.0.1", "localhost"),
) -> dict[str, Path]:
    """Write the lab CA (or reuse the one in ``out``), the router's and each name's certificate.

    Returns the directory of each party, the router's under ``"router"``.
    """
    for name in names:
        problem = name_problem(name)
        if problem:
            raise CertificateError(f"robot name {problem}")
    if ROUTER_DIR in names:
        raise CertificateError(f"{ROUTER_DIR!r} is the router's directory, not a robot name")
    if len(set(names)) != len(names):
        raise CertificateError(f"names must be unique, got {list(names)}")
    if not hosts:
        raise CertificateError("the router certificate needs at least one host")
    if days < 1:
        raise CertificateError(f"days must be at least 1, got {days}")
    out.mkdir(parents=True, exist_ok=True)
    if (out / CA_CERT).exists() and (out / CA_KEY).exists():
        issuer = load_ca(out)
        log.info("reusing the CA in %s", out)
    else:
        issuer = make_ca(ca_name, days)
        _write_cert(out / CA_CERT, issuer.certificate)
        _write_key(out / CA_KEY, issuer.key)
        log.info("made CA %r in %s", ca_name, out)
    dirs = {ROUTER_DIR: _write_party(out, issuer, ROUTER_DIR, days, hosts)}
    for name in names:
        dirs[name] = _write_party(out, issuer, name, days, ())
    return dirs
