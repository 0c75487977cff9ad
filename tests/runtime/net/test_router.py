"""The lab router: mutual TLS and access control, with real Zenoh on 127.0.0.1.

One ``percept router`` process serves the module; robots and tools are client sessions in this
process, each with the certificate ``percept certs`` made for it.
"""

from __future__ import annotations

import os
import queue
import signal
import stat
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh
from cryptography import x509

from percept.config import find
from percept.config.loader import ConfigError
from percept.runtime.cli import main
from percept.runtime.net.certs import CertificateError, make_lab_certificates
from percept.runtime.net.link import Link, LinkError
from percept.runtime.net.messages import PointingRequest, Signal, encode
from percept.runtime.net.router import access_control, load_router_settings
from percept.runtime.net.settings import NetworkSettings
from percept.runtime.net.zenoh_config import client_config, client_settings, config, peer_config
from tests.support.zenoh_rig import experiment, free_port

WAIT = 10.0  # generous: the machine is shared


def _router_file(directory: Path, port: int, **extra: str) -> Path:
    lines = {
        "listen": f'["tls/127.0.0.1:{port}"]',
        "ca": '"certs/router/ca.pem"',
        "certificate": '"certs/router/cert.pem"',
        "private_key": '"certs/router/key.pem"',
        "prefix": '"percept"',
        "robots": '["a", "b"]',
    } | extra
    text = "".join(f"{k} = {v}\n" for k, v in lines.items())
    text += '[[clients]]\nname = "monitor"\npublish = ["games/**"]\n'
    path = directory / "router.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _start_router(path: Path, log: Path) -> subprocess.Popen:
    with log.open("wb") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "percept.runtime.cli", "router", "--config", str(path)],
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    deadline = time.monotonic() + 30
    while "listening on" not in log.read_text(encoding="utf-8", errors="replace"):
        assert proc.poll() is None, log.read_text(encoding="utf-8", errors="replace")
        assert time.monotonic() < deadline, "router did not start"
        time.sleep(0.05)
    return proc


def _stop(proc: subprocess.Popen) -> int:
    proc.send_signal(signal.SIGTERM)
    try:
        return proc.wait(timeout=WAIT)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise


class Lab:
    """The running router, its certificates and a way to open client sessions."""

    def __init__(self, directory: Path, endpoint: str, log: Path) -> None:
        self.certs = directory / "certs"
        self.endpoint = endpoint
        self.log = log
        self.sessions: list[zenoh.Session] = []

    def connect(self, name: str, certs: Path | None = None) -> zenoh.Session:
        session = zenoh.open(client_config([self.endpoint], (certs or self.certs) / name))
        self.sessions.append(session)
        return session

    def wait_for_log(self, text: str) -> None:
        """Wait until the router's log holds ``text``: the router writes it from its own
        process, after or before the messages it lets through."""
        deadline = time.monotonic() + WAIT
        while text not in self.log.read_text(encoding="utf-8"):
            assert time.monotonic() < deadline, self.log.read_text(encoding="utf-8")
            time.sleep(0.05)


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Lab]:
    directory = tmp_path_factory.mktemp("lab")
    make_lab_certificates(directory / "certs", ["a", "b", "monitor", "viewer"])
    port = free_port()
    log = directory / "router.log"
    proc = _start_router(_router_file(directory, port), log)
    lab = Lab(directory, f"tls/127.0.0.1:{port}", log)
    try:
        yield lab
    finally:
        for session in lab.sessions:
            session.close()
        _stop(proc)


class Inbox:
    """What a subscriber received, (key, payload) in order, on a queue it can wait on."""

    def __init__(self) -> None:
        self.received: queue.Queue[tuple[str, str]] = queue.Queue()
        self.seen: list[tuple[str, str]] = []

    def __call__(self, sample: zenoh.Sample) -> None:
        self.received.put((str(sample.key_expr), sample.payload.to_string()))

    def wait_for(self, key: str, payload: str, send: Callable[[], None]) -> None:
        """Call ``send`` until (key, payload) arrives; raise if it does not within WAIT."""
        deadline = time.monotonic() + WAIT
        while time.monotonic() < deadline:
            send()
            try:
                while True:
                    self.seen.append(self.received.get(timeout=0.1))
                    if self.seen[-1] == (key, payload):
                        return
            except queue.Empty:
                continue
        raise AssertionError(f"{key} {payload!r} never arrived; got {self.seen}")


@pytest.mark.timeout(60)
def test_robot_publishes_under_its_name_and_anyone_with_a_lab_certificate_reads(lab: Lab) -> None:
    inbox = Inbox()
    lab.connect("viewer").declare_subscriber("percept/**", inbox)
    a = lab.connect("a")
    inbox.wait_for("percept/a/world", "hello", lambda: a.put("percept/a/world", "hello"))
    lab.wait_for_log("a connected from tls/127.0.0.1:")


@pytest.mark.timeout(60)
def test_robot_cannot_publish_as_another_robot(lab: Lab) -> None:
    inbox = Inbox()
    lab.connect("viewer").declare_subscriber("percept/**", inbox)
    a, viewer = lab.connect("a"), lab.connect("viewer")

    def send() -> None:
        # The forgeries go first on the same link: had they passed, they would arrive first.
        a.put("percept/b/world", "forged by a")
        a.put("percept/b", "forged by a")
        viewer.put("percept/viewer/world", "a reader publishing")
        a.put("percept/a/world", "marker")

    inbox.wait_for("percept/a/world", "marker", send)
    assert all(key == "percept/a/world" for key, _ in inbox.seen), inbox.seen


@pytest.mark.timeout(60)
def test_liveliness_token_only_under_own_name(lab: Lab) -> None:
    tokens: queue.Queue[str] = queue.Queue()
    lab.connect("viewer").liveliness().declare_subscriber(
        "percept/**", lambda s: tokens.put(str(s.key_expr))
    )
    a = lab.connect("a")
    forged = a.liveliness().declare_token("percept/b/alive")
    own = a.liveliness().declare_token("percept/a/alive")
    assert tokens.get(timeout=WAIT) == "percept/a/alive"
    time.sleep(0.5)  # a forged token, had it passed, would have come with the first
    assert tokens.empty()
    forged.undeclare()
    own.undeclare()


@pytest.mark.timeout(60)
def test_client_granted_extra_keys(lab: Lab) -> None:
    inbox = Inbox()
    lab.connect("a").declare_subscriber("percept/**", inbox)
    monitor = lab.connect("monitor")

    def send() -> None:
        monitor.put("percept/b/signal", "forged by monitor")
        monitor.put("percept/games/start", "go")

    inbox.wait_for("percept/games/start", "go", send)
    monitor.put("percept/monitor/status", "own key")
    inbox.wait_for("percept/monitor/status", "own key", lambda: None)
    assert ("percept/b/signal", "forged by monitor") not in inbox.seen


@pytest.mark.timeout(60)
def test_certificate_from_another_ca_is_refused(lab: Lab, tmp_path: Path) -> None:
    # The rogue robot may well hold the lab's public CA certificate; only its own is foreign.
    rogue = tmp_path / "rogue"
    make_lab_certificates(rogue, ["a"], ca_name="percept lab CA")
    (rogue / "a" / "ca.pem").write_bytes((lab.certs / "ca.pem").read_bytes())
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        lab.connect("a", certs=rogue)
    # Zenoh's warning in the router's log says why (same CA name, other key: BadSignature).
    lab.wait_for_log("invalid peer certificate")


@pytest.mark.timeout(60)
def test_router_from_another_ca_is_refused_by_the_robot(lab: Lab, tmp_path: Path) -> None:
    make_lab_certificates(tmp_path / "other", ["a"], ca_name="another lab CA")
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        lab.connect("a", certs=tmp_path / "other")


@pytest.mark.timeout(60)
def test_robot_without_certificate_is_refused(lab: Lab) -> None:
    settings = client_settings([lab.endpoint], lab.certs / "a")
    del settings["transport"]["link"]["tls"]["enable_mtls"]  # sends no client certificate
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        zenoh.open(config(settings)).close()


@pytest.mark.timeout(60)
def test_router_stops_cleanly_on_sigterm(tmp_path: Path) -> None:
    make_lab_certificates(tmp_path / "certs", ["a", "b", "monitor"])
    log = tmp_path / "router.log"
    proc = _start_router(_router_file(tmp_path, free_port()), log)
    assert _stop(proc) == 0
    assert "router closed" in log.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def certs_only(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("bad")
    make_lab_certificates(directory / "certs", ["a", "b", "monitor"])
    return directory


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"robots": '["a", 3]'}, "robots[1]: expected a string, got 3"),
        ({"robots": '["a", "b/c"]'}, "robots[1]: 'b/c': expected 1 to 64 letters, digits, - and _"),
        ({"robots": '["a", "a"]'}, "robots[1]: 'a' is named twice"),
        ({"robots": "[]"}, "robots: expected at least one robot name"),
        ({"listen": '["tcp/127.0.0.1:7447"]'}, "listen[0]: expected a tls/ endpoint, got"),
        ({"ca": '"certs/nowhere.pem"'}, "ca: file not found: "),
        ({"private_key": '"certs/router/cert.pem"'}, "private_key: "),
        ({"prefix": '"percept/*"'}, "prefix: 'percept/*' holds *: a key may not hold"),
        ({"robot": '["a"]'}, "robot: unknown key; expected one of: ca, certificate,"),
    ],
)
def test_bad_router_file_exits_2_naming_file_and_key(
    certs_only: Path, extra: dict[str, str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _router_file(certs_only, 7447, **extra)
    assert main(["router", "--config", str(path)]) == 2
    assert capsys.readouterr().err.startswith(f"percept: {path}: {message}")


def test_bad_publish_key_expression(certs_only: Path) -> None:
    path = _router_file(certs_only, 7447)
    text = path.read_text(encoding="utf-8").replace('"games/**"', '"games//x"')
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match=r"clients\[0\]\.publish\[0\]: Invalid Key Expr"):
        load_router_settings(path)


def test_certs_reuse_the_ca_and_protect_keys(tmp_path: Path) -> None:
    assert main(["certs", "--out", str(tmp_path), "--robots", "a", "b"]) == 0
    ca = (tmp_path / "ca.pem").read_bytes()
    assert main(["certs", "--out", str(tmp_path), "--robots", "c"]) == 0
    assert (tmp_path / "ca.pem").read_bytes() == ca
    authority = x509.load_pem_x509_certificate(ca)
    for name in ("a", "b", "c", "router"):
        cert = x509.load_pem_x509_certificate((tmp_path / name / "cert.pem").read_bytes())
        cert.verify_directly_issued_by(authority)
        assert cert.subject.rfc4514_string() == f"CN={name}"
        assert stat.S_IMODE(os.stat(tmp_path / name / "key.pem").st_mode) == 0o600
    assert stat.S_IMODE(os.stat(tmp_path / "ca.key").st_mode) == 0o600
    router = x509.load_pem_x509_certificate((tmp_path / "router" / "cert.pem").read_bytes())
    hosts = router.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert [str(h.value) for h in hosts] == ["127.0.0.1", "localhost"]


def test_certs_refuses_bad_names(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["certs", "--out", str(tmp_path), "--robots", "a", "a b"]) == 2
    assert "'a b': expected 1 to 64 letters, digits, - and _" in capsys.readouterr().err
    with pytest.raises(CertificateError, match="router"):
        make_lab_certificates(tmp_path, ["router"])
    # the name every message carries: a longer one would be refused in each message it sends
    with pytest.raises(CertificateError, match="1 to 64"):
        make_lab_certificates(tmp_path, ["b" * 65])


def test_client_settings_need_the_certificate_files(tmp_path: Path) -> None:
    with pytest.raises(CertificateError, match="missing certificate files"):
        client_settings(["tls/127.0.0.1:7447"], tmp_path)


@pytest.mark.timeout(60)
def test_peer_config_connects_two_peers_over_tcp() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    listener = zenoh.open(peer_config([endpoint]))
    try:
        talker = zenoh.open(peer_config([], [endpoint]))
        try:
            inbox = Inbox()
            listener.declare_subscriber("percept/**", inbox)
            inbox.wait_for("percept/a/boxes", "x", lambda: talker.put("percept/a/boxes", "x"))
        finally:
            talker.close()
    finally:
        listener.close()


def test_shipped_lab_file_loads_once_certificates_exist(tmp_path: Path) -> None:
    shipped = find("lab", "router")
    (tmp_path / "router.toml").write_text(shipped.read_text(encoding="utf-8"), encoding="utf-8")
    make_lab_certificates(tmp_path / "certs", ["a", "b", "c", "monitor"])
    settings = load_router_settings(tmp_path / "router.toml")
    assert settings.robots == ("a", "b", "c")
    assert settings.certificate == tmp_path / "certs" / "router" / "cert.pem"


def test_acl_ids_stay_unique_whatever_the_names(certs_only: Path) -> None:
    path = _router_file(certs_only, 7447, robots='["read", "deliver", "lab", "write"]')
    acl = access_control(load_router_settings(path))
    for part in ("rules", "subjects"):
        ids = [entry["id"] for entry in acl[part]]
        assert len(ids) == len(set(ids)), ids
    assert {"id": "cn read", "cert_common_names": ["read"]} in acl["subjects"]


@pytest.mark.timeout(60)
def test_percept_links_with_bs_certificate_cannot_speak_as_a_nor_without_one_at_all(
    lab: Lab,
) -> None:
    """The robots' own links in the lab deployment: a process holding b's certificate that
    names itself a sends a start signal and a pointing request as a, and none reaches anyone;
    b's own messages do. A process without a certificate cannot even open its link."""
    inbox = Inbox()
    lab.connect("viewer").declare_subscriber("percept/**", inbox)
    as_b = NetworkSettings(mode="client", connect=(lab.endpoint,), certificates=lab.certs / "b")
    exp = experiment("a", "b", network=as_b)
    with Link(exp, "a") as forger, Link(exp, "b") as b:
        marker = Signal("g-b", "b", "a", "failure")

        def send() -> None:
            forger.publish("signal", Signal("g-a", "a", "b", "start", "b", "a"))
            forger.publish("pointing", PointingRequest("g-a", "a", "b", 0.5, 0.0))
            b.publish("signal", marker)

        inbox.wait_for("percept/b/signal", encode(marker).decode(), send)
    assert not any(key.startswith("percept/a/") for key, _ in inbox.seen), inbox.seen
    plain = NetworkSettings(mode="client", connect=(lab.endpoint,))
    with pytest.raises(LinkError, match="cannot open a Zenoh session"):
        Link(experiment("a", "b", network=plain), "a")
