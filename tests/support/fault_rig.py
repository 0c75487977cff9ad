"""Faults injected into a running daemon, and how long it takes to say so and to recover.

A :class:`Rig` runs robot a's daemon (:class:`percept.runtime.daemon.daemon.Daemon`, the code
``percept run`` runs) in this process on the simulated world: the camera is the simulated one, the
servos are the Dynamixel emulator on a pseudo-terminal read by the real driver, and the network is
real Zenoh on 127.0.0.1. Robot b is a peer in a process of its own
(:mod:`tests.support.fault_peer`), and so are the bad senders. Faults go in through the stand-ins'
own fault hooks (the emulator's, the simulated camera's), through signals to the peer, and through
the network.

:meth:`Rig.measure` injects one fault, holds it, ends it and measures, from the status messages
seen on Zenoh and the daemon's log: the time from the fault to the first status naming it, to
the first log line naming it, and from the fault's end to the first status without any fault.
:data:`SCENARIOS` are the faults of ``tests/test_faults.py`` and ``bench/faults.py``.

A :class:`ProcessRig` runs ``percept run`` itself in a child process, for faults that need a
process of its own: a full disk, made by lowering the child's file size limit to 0
(``prlimit``), which refuses every write to every file as a full disk does, without root.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import re
import resource
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tests.support.daemon import EXPERIMENT as EXPERIMENT  # re-exported: test_faults reads it
from tests.support.daemon import ROOT, SCENE, endpoint, experiment_copy
from tests.support.zenoh_rig import PROFILE, free_port

PAN = 19  # head_pan's servo id in the OP3 profile

# Short timings for CI (the shipped ones otherwise): quicker status, stale peers and
# reconnects; a bus timeout that a loaded machine's pty emulator still meets.
SHORT_EXPERIMENT = {
    "daemon": {"status_interval": 0.5, "frame_timeout": 0.3},
    "peers": {"stale_after": 0.5},
}
SHORT_PROFILE = {
    "bus": {
        "timeout": 0.05,
        "stale_after": 0.3,
        "error_poll_interval": 0.25,
        "probe_interval": 0.1,
        "reconnect_backoff": [0.05, 0.5],
    },
    "camera": {"reconnect_backoff": [0.05, 0.5], "max_failures": 3},
}
READY_TIMEOUT = 90.0  # daemon start: MuJoCo, background calibration, a loaded CI machine


def _toml(value: Any) -> str:
    return json.dumps(value) if not isinstance(value, bool) else str(value).lower()


def _set_keys(text: str, tables: dict[str, dict[str, Any]]) -> str:
    """``text`` (TOML) with ``key = value`` put first in each ``[table]`` (added if missing)."""
    for table, keys in tables.items():
        lines = "".join(f"{k} = {_toml(v)}\n" for k, v in keys.items())
        header = f"[{table}]\n"
        for key in keys:  # drop the file's own setting of the key in that table
            text = re.sub(rf"(\[{table}\]\n(?:(?!\[).*\n)*?){key} = .*\n", r"\1", text, count=1)
        text = text.replace(header, header + lines, 1) if header in text else text + header + lines
    return text


def write_config(tmp: Path, short: bool = True) -> Path:
    """An experiment (and robot profile) in ``tmp``: free local ports, absolute paths, and
    with ``short`` the short timings."""
    profile = tmp / "robot.toml"
    text = PROFILE.read_text(encoding="utf-8")
    profile.write_text(_set_keys(text, SHORT_PROFILE) if short else text, encoding="utf-8")
    experiment = experiment_copy(tmp, ('"../robots/robotis-op3.toml"', json.dumps(str(profile))))
    if short:
        text = _set_keys(experiment.read_text(encoding="utf-8"), SHORT_EXPERIMENT)
        experiment.write_text(text, encoding="utf-8")
    return experiment


@dataclass
class Measurement:
    """One fault: seconds to the first status naming it (``reported``), to the first log line
    naming it (``logged``) and from its end to the first status without faults
    (``recovered``); None: not within the time allowed. ``words`` is the fault as the status
    said it, ``status`` that whole status message."""

    fault: str
    reported: float | None = None
    logged: float | None = None
    recovered: float | None = None
    words: str = ""
    status: dict[str, Any] = field(default_factory=dict)
    began_wall: float = 0.0
    ended_wall: float = 0.0


class StatusWatch:
    """A Zenoh client on a robot's endpoint keeping its status and world messages with the
    (monotonic) time each arrived."""

    def __init__(self, ep: str) -> None:
        import zenoh

        from percept.runtime.net.zenoh_config import client_config

        self.statuses: list[tuple[float, dict[str, Any]]] = []
        self.worlds: list[tuple[float, dict[str, Any]]] = []
        self._lock = threading.Lock()
        self.session = zenoh.open(client_config([ep], connect_timeout=None))
        self._subs = [
            self.session.declare_subscriber("percept/a/status", self._on(self.statuses)),
            self.session.declare_subscriber("percept/a/world", self._on(self.worlds)),
        ]

    def _on(self, into: list[tuple[float, dict[str, Any]]]) -> Callable[[Any], None]:
        def callback(sample: Any) -> None:
            message = json.loads(sample.payload.to_bytes())
            with self._lock:
                into.append((time.monotonic(), message))

        return callback

    def first_status(
        self, after: float, predicate: Callable[[dict[str, Any]], bool], timeout: float
    ) -> tuple[float, dict[str, Any]] | None:
        """The first status that arrived after ``after`` and satisfies ``predicate``."""
        deadline = time.monotonic() + timeout
        seen = 0
        while True:
            with self._lock:
                fresh = self.statuses[seen:]
                seen = len(self.statuses)
            for t, status in fresh:
                if t >= after and predicate(status):
                    return t, status
            if time.monotonic() > deadline:
                return None
            time.sleep(0.01)

    def world_stamps(self, before: float = float("inf")) -> set[float]:
        """Stamps of the world models received before monotonic time ``before``."""
        with self._lock:
            return {w["stamp"] for t, w in self.worlds if t < before}

    def close(self) -> None:
        self.session.close()


class LogWatch(logging.Handler):
    """The lines logged under ``percept``, with the (monotonic) time of each."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.lines: list[tuple[float, str]] = []
        self._lock_lines = threading.Lock()

    def emit(self, record: logging.LogRecord) -> None:
        line = f"{record.levelname} {record.name}: {record.getMessage()}"
        with self._lock_lines:
            self.lines.append((time.monotonic(), line))

    def add(self, t: float, line: str) -> None:
        with self._lock_lines:
            self.lines.append((t, line))

    def first(self, after: float, words: str, timeout: float) -> float | None:
        """When the first line after ``after`` containing ``words`` was logged."""
        deadline = time.monotonic() + timeout
        while True:
            with self._lock_lines:
                hits = [t for t, line in self.lines if t >= after and words in line]
            if hits:
                return hits[0]
            if time.monotonic() > deadline:
                return None
            time.sleep(0.01)


class Peer:
    """Robot b in a process of its own (``python -m tests.support.fault_peer peer``)."""

    def __init__(self, experiment: Path, name: str = "b") -> None:
        self.experiment, self.name = experiment, name
        self.proc: subprocess.Popen[str] | None = None

    def start(self) -> float:
        """Start it; the (monotonic) time of its first box message."""
        cmd = [
            sys.executable,
            "-m",
            "tests.support.fault_peer",
            "peer",
            str(self.experiment),
            self.name,
        ]
        self.proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, encoding="utf-8")
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line.startswith("ready "):
            raise RuntimeError(f"peer {self.name} did not start: {line!r}")
        return float(line.split()[1])

    def signal(self, sig: int) -> float:
        assert self.proc is not None
        self.proc.send_signal(sig)
        return time.monotonic()

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGCONT)
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


class Sender:
    """A bad sender in a process of its own (``python -m tests.support.fault_peer send``)."""

    def __init__(self, ep: str, kind: str, count: int, rate: float) -> None:
        self.args = [ep, kind, str(count), str(rate)]
        self.proc: subprocess.Popen[str] | None = None

    def start(self) -> float:
        """Start sending; the (monotonic) time of the first message."""
        cmd = [sys.executable, "-m", "tests.support.fault_peer", "send", *self.args]
        self.proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, encoding="utf-8")
        return self._time("start")

    def wait(self) -> float:
        """Wait until it is done; the (monotonic) time of its last message."""
        t = self._time("end")
        assert self.proc is not None
        self.proc.wait(10)
        return t

    def _time(self, word: str) -> float:
        assert self.proc is not None and self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line.startswith(word + " "):
            self.proc.kill()
            raise RuntimeError(f"sender {self.args}: expected {word!r}, got {line!r}")
        return float(line.split()[1])


class _Base:
    """What both rigs share: the status watch, the log and the measurement."""

    watch: StatusWatch
    logs: LogWatch

    def alive(self) -> bool:
        raise NotImplementedError

    def wait_healthy(self, timeout: float = READY_TIMEOUT) -> dict[str, Any]:
        """The first status (from now) without faults."""
        got = self.watch.first_status(time.monotonic(), lambda s: not s["faults"], timeout)
        if got is None:
            last = self.watch.statuses[-1][1]["faults"] if self.watch.statuses else "no status"
            raise AssertionError(f"robot a not healthy within {timeout} s: {last}")
        return got[1]

    def measure(
        self,
        fault: str,
        expect: str,
        inject: Callable[[], float | None],
        end: Callable[[], float | None],
        hold: float = 0.5,
        report_timeout: float = 5.0,
        recover_timeout: float = 15.0,
    ) -> Measurement:
        """Inject a fault (``inject`` returns when it began, None: now), hold it ``hold``
        seconds after the status named it, end it (``end`` likewise) and measure."""
        self.wait_healthy(30.0)

        def named(status: dict[str, Any]) -> bool:
            return any(expect in f for f in status["faults"])

        m = Measurement(fault)
        m.began_wall = time.time()
        began = inject() or time.monotonic()
        got = self.watch.first_status(began, named, report_timeout)
        if got is not None:
            m.reported = got[0] - began
            m.status = got[1]
            m.words = next(f for f in got[1]["faults"] if expect in f)
        logged = self.logs.first(began, expect, 1.0 if got else 0.0)
        m.logged = None if logged is None else logged - began
        time.sleep(hold)
        m.ended_wall = time.time()
        ended = end() or time.monotonic()
        healed = self.watch.first_status(ended, lambda s: not s["faults"], recover_timeout)
        m.recovered = None if healed is None else healed[0] - ended
        return m


class Rig(_Base):
    """Robot a's daemon in this process, recorded; robot b as a peer process."""

    def __init__(self, tmp: Path, short: bool = True, scene: str = SCENE) -> None:
        self.tmp = tmp
        self.experiment = write_config(tmp, short)
        self.record = tmp / "a.mcap"
        self.scene = scene
        self.daemon: Any = None
        self.logs = LogWatch()
        self.peer = Peer(self.experiment)
        self.impostors: list[Impostor] = []

    def start(self) -> Rig:
        from percept.runtime.daemon.daemon import Daemon
        from percept.runtime.daemon.settings import DaemonOptions
        from percept.runtime.settings.experiment import load_experiment
        from percept.runtime.settings.scene import find_scene

        logger = logging.getLogger("percept")
        logger.addHandler(self.logs)
        if logger.getEffectiveLevel() > logging.INFO:
            logger.setLevel(logging.INFO)
        options = DaemonOptions(
            robot="a",
            profile_path=load_experiment(self.experiment).robot("a").profile,
            experiment_path=self.experiment,
            sim_scene=str(find_scene(self.scene)),
            record=self.record,
        )
        self.daemon = Daemon(options)
        self.daemon.start()
        self.watch = StatusWatch(endpoint(self.experiment, "a"))
        self.peer.start()
        self.wait_healthy()
        return self

    @property
    def emulator(self) -> Any:
        from percept.drivers.dynamixel.emulator import ServoEmulator

        return next(x for x in self.daemon.devices.stand_ins if isinstance(x, ServoEmulator))

    @property
    def camera(self) -> Any:
        return self.daemon.devices.camera

    def alive(self) -> bool:
        return self.daemon.error is None and all(t.is_alive() for t in self.daemon._threads)

    def send(self, kind: str, count: int, rate: float) -> Sender:
        return Sender(endpoint(self.experiment, "a"), kind, count, rate)

    def stop(self) -> float:
        """Stop the daemon (the recording is closed); the (monotonic) time it began stopping."""
        began = time.monotonic()
        if self.daemon is not None:
            self.daemon.stop()
        return began

    def close(self) -> None:
        self.peer.stop()
        self.stop()
        if hasattr(self, "watch"):
            self.watch.close()
        logging.getLogger("percept").removeHandler(self.logs)


class ProcessRig(_Base):
    """``percept run`` as robot a in a child process, recorded; its log read from stderr."""

    def __init__(
        self, tmp: Path, short: bool = True, scene: str = SCENE, extra: tuple[str, ...] = ()
    ) -> None:
        self.experiment = write_config(tmp, short)
        self.record = tmp / "a.mcap"
        self.scene = scene
        self.extra = extra  # more options of percept run
        self.logs = LogWatch()
        self.proc: subprocess.Popen[str] | None = None

    def start(self) -> ProcessRig:
        cmd = [
            sys.executable,
            "-m",
            "percept.runtime.cli",
            "run",
            "--experiment",
            str(self.experiment),
        ]
        cmd += ["--name", "a", "--sim", self.scene, "--record", str(self.record), *self.extra]
        env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
        self.proc = subprocess.Popen(
            cmd, cwd=ROOT, env=env, stderr=subprocess.PIPE, encoding="utf-8"
        )
        threading.Thread(target=self._read_log, daemon=True).start()
        self.watch = StatusWatch(endpoint(self.experiment, "a"))
        self.wait_healthy()
        return self

    def _read_log(self) -> None:
        assert self.proc is not None and self.proc.stderr is not None
        for line in self.proc.stderr:
            self.logs.add(time.monotonic(), line.rstrip())

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def file_size_limit(self, soft: int) -> float:
        """Set the daemon's file size limit (0: no file can grow, as on a full disk)."""
        assert self.proc is not None
        _, hard = resource.prlimit(self.proc.pid, resource.RLIMIT_FSIZE)
        resource.prlimit(self.proc.pid, resource.RLIMIT_FSIZE, (soft, hard))
        return time.monotonic()

    def stop(self) -> int:
        """SIGTERM; the exit code."""
        assert self.proc is not None
        self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()

    def close(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.stop()
        if hasattr(self, "watch"):
            self.watch.close()


@dataclass(frozen=True)
class Scenario:
    """One fault: what the status says (``expect``), how it starts and how it ends, and what
    else the status must show while it lasts (``shows``: a test of the status message)."""

    name: str
    expect: str
    inject: Callable[[Rig], float | None]
    end: Callable[[Rig], float | None]
    shows: Callable[[dict[str, Any]], bool] = lambda status: True


def _sender(kind: str, count: int, rate: float) -> tuple[Callable, Callable]:
    senders: list[Sender] = []

    def inject(rig: Rig) -> float:
        senders.append(rig.send(kind, count, rate))
        return senders[-1].start()

    def end(rig: Rig) -> float:
        return senders.pop().wait()

    return inject, end


def _peer_killed(rig: Rig) -> float:
    t = rig.peer.signal(signal.SIGKILL)
    assert rig.peer.proc is not None
    rig.peer.proc.wait()
    return t


def _stale(status: dict[str, Any]) -> bool:
    servos = status["servos"]
    return servos["stale"] == ["head_pan"] and "head_pan" in servos["not_answering"]


def _unheard(status: dict[str, Any]) -> bool:
    return status["peers"]["b"]["heard"] is False


def _rejected(status: dict[str, Any]) -> bool:
    return status["rejected_messages"] > 0


def _break_world(rig: Rig) -> None:
    """A bug in the daemon's own world model (a negative frame number, which the schema
    refuses), until :func:`_mend_world`."""
    step = rig.daemon.pipeline.step

    def broken(*args: Any, **kwargs: Any) -> Any:
        out = step(*args, **kwargs)
        if out.world is not None:
            out.world = dataclasses.replace(out.world, frame=-1)
        return out

    rig.daemon.pipeline.step = broken


def _mend_world(rig: Rig) -> None:
    del rig.daemon.pipeline.step  # the class's own again


class Impostor:
    """A second daemon's link named a, which met nobody when it started (its robot b's
    endpoint is not up), and then a process that dials both a's: the two meet later, as when
    two networks are joined."""

    def __init__(self, rig: Rig) -> None:
        import zenoh

        from percept.runtime.net.link import Link
        from percept.runtime.net.zenoh_config import peer_config
        from percept.runtime.settings.experiment import Experiment, RobotEntry

        mine, nobody = (f"tcp/127.0.0.1:{free_port()}" for _ in range(2))
        robots = (RobotEntry("a", PROFILE, mine), RobotEntry("b", PROFILE, nobody))
        self.link = Link(Experiment(name="other", robots=robots), "a", exclusive=True)
        a = endpoint(rig.experiment, "a")
        self.began = time.monotonic()
        self.bridge = zenoh.open(peer_config([], [mine, a]))

    def close(self) -> float:
        self.link.close()
        ended = time.monotonic()
        self.bridge.close()
        return ended


def _impostor(rig: Rig) -> float:
    rig.impostors.append(Impostor(rig))
    return rig.impostors[-1].began


def _strangers_ignored(status: dict[str, Any]) -> bool:
    return status["games"]["ignored"] > 0 and status["games"]["played"] == 0


def _far_rejected(status: dict[str, Any]) -> bool:
    return status["peers"]["b"]["implausible"] > 0


SCENARIOS = [
    Scenario(
        "camera stops delivering",
        "no frame",
        lambda r: r.camera.stall(),
        lambda r: r.camera.resume(),
        lambda s: s["camera"]["state"] == "connected",  # the driver cannot tell; the daemon can
    ),
    Scenario(
        "camera unplugged",
        "camera reconnecting",
        lambda r: r.camera.unplug(),
        lambda r: r.camera.replug(),
        lambda s: s["camera"]["state"] == "reconnecting",
    ),
    Scenario(
        "servo mute",
        "joint head_pan stale",
        lambda r: r.emulator.mute(PAN),
        lambda r: r.emulator.mute(PAN, False),
        _stale,
    ),
    Scenario(
        "servo corrupt CRC",
        "joint head_pan stale",
        lambda r: r.emulator.corrupt(PAN),
        lambda r: r.emulator.clear_faults(PAN),
        _stale,
    ),
    Scenario(
        "servo short replies",
        "joint head_pan stale",
        lambda r: r.emulator.short_reply(PAN),
        lambda r: r.emulator.clear_faults(PAN),
        _stale,
    ),
    Scenario(
        "servo error bits",
        "servo head_pan reports",
        lambda r: r.emulator.set_hardware_error(PAN, 0x24),  # overheating, overload
        lambda r: r.emulator.clear_faults(PAN),
        lambda s: len(s["servos"]["errors"]["head_pan"]) == 2,
    ),
    Scenario(
        "servo bus unplugged",
        "servos reconnecting",
        lambda r: r.emulator.unplug(),
        lambda r: r.emulator.replug(),
        lambda s: s["servos"]["state"] == "reconnecting",
    ),
    Scenario(
        "peer killed, restarted",
        "peer b not heard",
        _peer_killed,
        lambda r: r.peer.start(),
        _unheard,
    ),
    Scenario(
        "peer frozen (SIGSTOP)",
        "peer b not heard",
        lambda r: r.peer.signal(signal.SIGSTOP),
        lambda r: r.peer.signal(signal.SIGCONT),
        _unheard,
    ),
    Scenario(
        "malformed payloads",
        "rejecting messages on percept/c/boxes: not a JSON message",
        *_sender("malformed", 20, 50.0),
        _rejected,
    ),
    Scenario(
        "wrong schema",
        "rejecting messages on percept/c/boxes: payload: expected schema",
        *_sender("wrong-schema", 20, 50.0),
        _rejected,
    ),
    Scenario(
        "oversized payloads",
        "rejecting messages on percept/c/boxes: payload of",
        *_sender("oversized", 20, 50.0),
        _rejected,
    ),
    Scenario(
        "forged sender",
        "rejecting messages on percept/b/boxes: sent by 'c'",
        *_sender("forged", 20, 50.0),
        _rejected,
    ),
    Scenario(
        "garbage on 300 keys",
        "rejecting messages on percept/c0",
        *_sender("many-keys", 300, 300.0),
        lambda s: len(s["faults"]) <= 64 and all(len(f) <= 240 for f in s["faults"]),
    ),
    Scenario(
        "flood at 1 kHz",
        "flood on percept/c/",
        *_sender("flood", 3000, 1000.0),
        lambda s: s["fps"] > 0,
    ),
    Scenario(
        "peer boxes 10 km away",
        "implausible data from peer b rejected: box 1 1.414e+04 m from it",
        *_sender("far-boxes", 20, 50.0),
        _far_rejected,
    ),
    Scenario(
        "games from made-up robots",
        "flood on percept/*/pointing from c0, c1, c2, c3, c4 and 5 more",
        *_sender("strangers", 600, 300.0),
        _strangers_ignored,
    ),
    Scenario(
        "own world model invalid",
        "own world messages fail their check, not sent: percept.world/2.frame",
        _break_world,
        _mend_world,
        lambda s: s["unsent_messages"] > 0,
    ),
    Scenario(
        "second robot named a",
        "another process runs as a on the network",
        _impostor,
        lambda r: r.impostors.pop().close(),
    ),
]


def disk_full(rig: ProcessRig, hold: float = 0.5) -> Measurement:
    """The recording's disk fills up (the daemon's file size limit drops to 0) and is freed."""
    return rig.measure(
        "recording disk full",
        "recording failed",
        lambda: rig.file_size_limit(0),
        lambda: rig.file_size_limit(resource.RLIM_INFINITY),
        hold,
    )
