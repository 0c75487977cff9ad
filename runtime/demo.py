"""``percept demo``: two simulated robots, their daemons, the joint-attention monitor and the
pointing game, then a summary against the simulated truth.

Each robot is its own ``percept run --sim SCENE`` process with its servos read through the
Dynamixel emulator. Every daemon runs its own copy of the simulated world; the world is a pure
function of scene time, and all daemons get the same ``--sim-epoch`` (wall-clock time of scene
time 0), so they see the same scene at the same moment without sharing a process. The demo itself
subscribes to every robot's world and status on Zenoh (for the progress line), runs the
joint-attention monitor and the pointing game, and when the time is up stops the daemons with
SIGTERM and reads their recordings to score them against the truth it computes from the scene.
"""

from __future__ import annotations

import json
import logging
import math
import os
import secrets
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from percept.runtime.net.messages import Message, Status, World, sender

if TYPE_CHECKING:
    from percept.drivers.sim.scene import Scene
    from percept.runtime.games.monitor import AttentionEvent
    from percept.runtime.record.summary import Summary
    from percept.runtime.settings.experiment import Experiment

log = logging.getLogger("percept.demo")

STOP_GRACE = 20.0
"""Seconds a daemon gets to stop after SIGTERM before it is killed. A daemon stops within two
seconds, but one stopped while its kernels still compile finishes compiling first (tens of
seconds on a loaded machine)."""
SCORE_LEAD = 3.0
"""Seconds the demo goes on at least after the last robot got its background model: world
models to score."""
READY_WAIT = 120.0
"""Seconds past ``--seconds`` the demo waits for every robot's background model: a demo shorter
than the calibration, or on a loaded machine, goes on until there is something to score."""
START_LEAD = 3.0  # seconds from launching the daemons to scene time 0
SWEEP_LEAD = 8.0  # the same when heads sweep: a daemon takes 3-7 s to start on a loaded machine


@dataclass(frozen=True)
class DemoOptions:
    """What ``percept demo`` was asked to do."""

    scene: Path
    seconds: float
    out: Path
    experiment: str | Path
    log_level: str = "INFO"
    gaze: bool | None = None
    """The daemons move the heads (``percept run --enable-gaze``); None: when the scene's
    heads move."""


class Daemons:
    """The robots' ``percept run`` processes; their stderr goes to ``<out>/<robot>.log``, their
    recordings to ``records``: ``<out>/<robot>.mcap``, or the next free name if a
    recording of an earlier run is there (it is kept)."""

    def __init__(
        self,
        options: DemoOptions,
        robots: list[str],
        epoch: float,
        profiles: dict[str, Path | str],
        gaze: bool = False,
        network: tuple[str, ...] = (),
    ) -> None:
        from percept.runtime.record.writer import free_name

        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.killed: set[str] = set()  # did not stop in time after SIGTERM
        self.records = {r: free_name(options.out / f"{r}.mcap") for r in robots}
        self._logs = []
        self.log_files = {robot: options.out / f"{robot}.log" for robot in robots}
        for robot in robots:
            # The scene simulates each robot's body: its daemon runs with that profile.
            body = ["--robot", str(profiles[robot])] if robot in profiles else []
            cmd = [
                sys.executable,
                "-m",
                "percept.runtime.cli",
                "run",
                "--log-level",
                options.log_level,
                "--experiment",
                str(options.experiment),
                "--name",
                robot,
                "--sim",
                str(options.scene),
                "--sim-epoch",
                repr(epoch),
                "--record",
                str(self.records[robot]),
                *body,
                *network,
                *(["--enable-gaze"] if gaze else []),
            ]
            logfile = self.log_files[robot].open("wb")
            self._logs.append(logfile)
            self.procs[robot] = subprocess.Popen(
                cmd, stdin=subprocess.DEVNULL, stdout=logfile, stderr=subprocess.STDOUT, env=_env()
            )
            log.info(
                "robot %s: pid %d, log %s, recording %s",
                robot,
                self.procs[robot].pid,
                logfile.name,
                self.records[robot],
            )

    def failed(self) -> dict[str, int]:
        """Daemons that ended on their own, with their exit codes."""
        return {r: p.returncode for r, p in self.procs.items() if p.poll() is not None}

    def stop(self) -> dict[str, int]:
        """SIGTERM all, wait up to :data:`STOP_GRACE` s, SIGKILL the rest; exit codes."""
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + STOP_GRACE
        codes = {}
        for robot, proc in self.procs.items():
            try:
                codes[robot] = proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
                self.killed.add(robot)
                codes[robot] = proc.wait()
        for logfile in self._logs:
            logfile.close()
        return codes


@dataclass
class _Live:
    """A robot's latest world model and status heard on Zenoh, for the progress line."""

    world: World | None = None
    status: Status | None = None

    def heard(self, message: Message) -> None:
        if isinstance(message, World):
            self.world = message
        elif isinstance(message, Status):
            self.status = message


def _progress(elapsed: float, total: float, live: dict[str, _Live], games: str) -> str:
    from percept.runtime.console import robot_part

    parts = [f"{elapsed:5.1f}/{total:.0f} s"]
    parts += [f"{robot}: {robot_part(s.status, s.world)}" for robot, s in sorted(live.items())]
    if games:
        parts.append(games)
    return " | ".join(parts)


def _games(events: list[AttentionEvent], live: dict[str, _Live]) -> str:
    """The progress line's games: joint attention, games started, and each robot's guessing
    games won and played (its agent's words)."""
    joint = sum(e["event"] == "joint_attention" for e in events)
    started = sum("game" in e for e in events)
    parts = [f"joint attention x{joint}, games {started}"]
    for robot, state in sorted(live.items()):
        if state.status is not None:
            g = state.status.games
            parts.append(
                f"{robot} guessing {g.get('guessing_success', 0)}/{g.get('guessing_played', 0)}"
                f" ({g.get('lexicon_size', 0)} words)"
            )
    return ", ".join(parts)


def _tty_line(text: str) -> None:
    if sys.stdout.isatty():
        sys.stdout.write("\r\x1b[K" + text)
    else:
        sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _ready(state: _Live) -> bool:
    """Whether the robot has its background model (it makes world models from now on)."""
    return state.status is not None and state.status.background.startswith(("calibrated", "loaded"))


def _isolated(experiment: Experiment) -> tuple[Experiment, tuple[str, ...]]:
    """The experiment on a key prefix and free ports of the demo's own, and the daemons'
    options saying so: two demos, or a demo and a daemon, on one machine never hear each
    other."""
    from percept.runtime.net.ports import free_port
    from percept.runtime.settings.experiment import on_network

    prefix = f"{experiment.prefix}/demo-{secrets.token_hex(3)}"
    endpoints = {r.name: f"tcp/127.0.0.1:{free_port()}" for r in experiment.robots}
    options = ["--prefix", prefix]
    for robot, endpoint in endpoints.items():
        options += ["--endpoint", f"{robot}={endpoint}"]
    log.info(
        "network: key prefix %s, %s",
        prefix,
        ", ".join(f"robot {r} on {e}" for r, e in endpoints.items()),
    )
    return on_network(experiment, prefix, endpoints), tuple(options)


def _report_stops(daemons: Daemons, codes: dict[str, int], failed: dict[str, int]) -> None:
    """Say how each daemon ended that did not end well, in its own words where it has some."""
    for robot, code in codes.items():
        log_file = daemons.log_files[robot]
        if robot in daemons.killed:
            log.error(
                "robot %s did not stop within %.0f s of SIGTERM and was killed (its recording "
                "may end early; log: %s)",
                robot,
                STOP_GRACE,
                log_file,
            )
        elif failed and robot not in failed:
            log.warning("robot %s was stopped because %s failed", robot, ", ".join(failed))
        elif code != 0:
            log.error(
                "robot %s ended with exit code %s: %s (log: %s)",
                robot,
                code,
                last_problem(log_file),
                log_file,
            )


def write_summary(out: Path, summary: Summary) -> Path:
    path = out / "summary.json"
    path.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return path


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("MUJOCO_GL", "egl")
    return env


def last_problem(log_file: Path) -> str:
    """The last error a daemon's log holds (``percept: ...`` or an ERROR line), in its words."""
    try:
        lines = log_file.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as err:
        return f"log unreadable ({err.strerror})"
    for line in reversed(lines):
        if line.startswith("percept: ") or " ERROR " in line:
            return line.removeprefix("percept: ").split(" ERROR   ", 1)[-1]
    return "no error in its log"


def demo_gaze(scene: Scene, asked: bool | None) -> bool:
    """Whether the demo's daemons move the heads (``percept run --enable-gaze``): as asked, or
    else when the scene's heads move. Robots that look around then move their heads
    themselves, through the emulated servos (never a real bus: the demo only simulates), and
    the scene's head keyframes are not played."""
    from percept.runtime.daemon.devices import head_sweep

    if asked is not None:
        return asked
    return any(head_sweep(scene, r.name) > 0 for r in scene.robots)


def run_demo(options: DemoOptions) -> int:
    """Run the demo; the exit code (0 when both daemons ran and stopped cleanly)."""
    from percept.config.loader import load
    from percept.drivers.sim.scene import Scene
    from percept.perception.warm import warm_up
    from percept.runtime.daemon.devices import head_sweep
    from percept.runtime.games.monitor import MonitorService
    from percept.runtime.net.link import Link
    from percept.runtime.settings.experiment import load_experiment
    from percept.runtime.settings.scene import robot_profile

    warm_up()  # once for both daemons, outside the demo's time (tens of seconds the first time)
    began = time.monotonic()
    options.out.mkdir(parents=True, exist_ok=True)
    experiment = load_experiment(options.experiment)
    robots = [r.name for r in experiment.robots]
    scene = load(Scene, options.scene)
    profiles = {r.name: robot_profile(r) for r in scene.robots}
    moves = any(head_sweep(scene, r.name) > 0 for r in scene.robots)
    gaze = demo_gaze(scene, options.gaze)
    # Scene time 0 after start-up: a still head's calibration sees the empty floor whenever it
    # starts (so does one that gaze sweeps: the scene is held at time 0 meanwhile), a head the
    # scene sweeps only while the sweep lasts, so it gets the longer lead.
    sweeps = moves and not gaze
    epoch = time.time() + (SWEEP_LEAD if sweeps else START_LEAD)
    if gaze:
        log.info("gaze on: the daemons move the simulated heads (emulated servos)")
    experiment, network = _isolated(experiment)
    daemons = Daemons(options, robots, epoch, profiles, gaze, network)
    live = {r: _Live() for r in robots}
    events: list[AttentionEvent] = []
    # The monitor's name: the daemons heed start signals from it (and the players) only.
    link = Link(experiment, experiment.peers.monitor, listen=[])
    for topic in ("world", "status"):
        link.subscribe(topic, lambda m: live[sender(m)].heard(m))
    MonitorService(link, robots, experiment.peers, emit=events.append)
    failed: dict[str, int] = {}
    unready: list[str] = []
    ready_at = math.inf  # when the last robot got its background model
    try:
        while True:
            elapsed = time.monotonic() - began
            failed = daemons.failed()
            unready = [r for r in robots if not _ready(live[r])]
            if not unready:
                ready_at = min(ready_at, elapsed)
            ends = max(options.seconds, ready_at + SCORE_LEAD)
            if failed or elapsed >= ends or elapsed >= options.seconds + READY_WAIT:
                break
            line = _progress(elapsed, options.seconds, live, _games(events, live))
            if elapsed >= options.seconds:
                waits = f"the background model of {', '.join(unready)}" if unready else "frames"
                line = f"waiting for {waits} | {line}"
            _tty_line(line)
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        codes = daemons.stop()
        link.close()
    print()
    _report_stops(daemons, codes, failed)
    if failed:  # a daemon gave up early: there is nothing to score
        print(f"demo failed: {', '.join(sorted(failed))} stopped early; see the logs above")
        return 1
    seconds = time.monotonic() - began
    if unready:
        print(
            f"no background model for {', '.join(unready)} after {seconds:.0f} s: the machine "
            "may be too busy; scoring what there is"
        )
    elif seconds > options.seconds + 2.0:
        print(f"ran {seconds:.0f} s instead of {options.seconds:g}: waited for the calibration")
    from percept.runtime.record.summary import summarise

    summary = summarise(replace(options, seconds=seconds), daemons.records, epoch, events)
    summary["exit_codes"] = codes
    summary["seconds"] = round(seconds, 1)
    write_summary(options.out, summary)
    print(f"summary: {options.out / 'summary.json'}, figure: {options.out / 'figure.png'}")
    return 0 if all(c == 0 for c in codes.values()) and not unready else 1
