"""The onboard daemon: one process per robot, from camera and servos to the network.

Threads (SPEC §2):

- the camera's reader thread and the servo bus's reader thread (inside the drivers; each keeps
  only fresh data, reconnects by itself and reports its state),
- in simulation, the simulated world's thread that feeds the servo emulator,
- ``perception``: takes the newest frame, the joint angles at its time and the peer messages
  that arrived since the last frame, runs the :class:`~percept.runtime.daemon.pipeline.Pipeline`,
  publishes the world model and logs it (recording, live view),
- ``markers``: the marker search on every ``[landmarks] every``-th frame (or the next one when
  it is still busy), whose result the perception thread applies at the next frame: the search
  (about 45 ms at 640x480) does not hold up the world models of the frames meanwhile,
- ``publisher``: the robot's box poses at 5 Hz and its status at 1 Hz,
- Zenoh's own threads, whose callbacks only put messages into bounded queues.

The main thread waits for SIGINT or SIGTERM and then stops everything within two seconds,
recording first.
"""

from __future__ import annotations

import collections
import logging
import math
import os
import resource
import statistics
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from percept.runtime.net.mailbox import DropOldest

if TYPE_CHECKING:
    from percept.runtime.daemon.gaze import Gaze

log = logging.getLogger("percept.daemon")

FAULT_CHECK = 0.1  # seconds between looks at the faults (a change publishes the status at once)
FAULT_WORDS = 240  # characters of one fault at most


@dataclass(frozen=True)
class DaemonSettings:
    """The experiment's ``[daemon]`` table: rates and bounds of the onboard daemon."""

    world_rate: float = field(
        default=0.0,
        metadata={
            "min": 0.0,
            "max": 1000.0,
            "doc": "world models per second on Zenoh; 0: every frame",
        },
    )
    joint_max_age: float = field(
        default=0.05,
        metadata={
            "min": 0.0,
            "doc": "seconds: a frame whose joint readings are older is marked (pose_fresh false)",
        },
    )
    status_interval: float = field(
        default=1.0, metadata={"min": 0.1, "max": 60.0, "doc": "seconds between status messages"}
    )
    frame_timeout: float = field(
        default=0.5,
        metadata={"min": 0.05, "doc": "seconds without a frame before it is reported as a fault"},
    )
    inbox: int = field(
        default=64,
        metadata={"min": 1, "max": 100000, "doc": "bound of each queue of received messages"},
    )
    flood_rate: float = field(
        default=100.0,
        metadata={
            "min": 1.0,
            "doc": "messages per second on one received key above which it is reported as a flood",
        },
    )


@dataclass(frozen=True)
class DaemonOptions:
    """What ``percept run`` was asked to do."""

    robot: str
    profile_path: Path
    experiment_path: Path
    sim_scene: str | None = None
    record: Path | None = None
    raw_images: bool = False
    view_port: int | None = None
    background: Path | None = None
    sim_epoch: float | None = None


class _Rate:
    """Frames per second and processing times over the last few seconds."""

    def __init__(self, window: float = 2.0) -> None:
        self.window = window
        self._times: collections.deque[float] = collections.deque()
        self._costs: collections.deque[float] = collections.deque(maxlen=256)

    def add(self, now: float, cost: float) -> None:
        self._times.append(now)
        self._costs.append(cost)
        while self._times and self._times[0] < now - self.window:
            self._times.popleft()

    def fps(self) -> float:
        times = self._times
        if len(times) < 2 or time.monotonic() - times[-1] > self.window:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def ms_median(self) -> float | None:
        return round(statistics.median(self._costs) * 1000, 2) if self._costs else None


class _Cpu:
    """This process's CPU use (fraction of one core) since the last call."""

    def __init__(self) -> None:
        self._last = (time.monotonic(), time.process_time())

    def sample(self) -> float:
        now = (time.monotonic(), time.process_time())
        wall, cpu = now[0] - self._last[0], now[1] - self._last[1]
        self._last = now
        return round(cpu / wall, 3) if wall > 0 else 0.0


def resident_mb() -> float:
    """Resident memory of this process in MB (current, from /proc; peak where unavailable)."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
        return round(pages * os.sysconf("SC_PAGE_SIZE") / 1e6, 1)
    except (OSError, ValueError, IndexError):
        return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3, 1)


def _finite(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else round(value, 4)


class Daemon:
    """One robot's onboard process; see the module doc for its threads."""

    def __init__(self, options: DaemonOptions) -> None:
        from percept.runtime.settings.experiment import check_gaze, load_experiment
        from percept.runtime.settings.profile import load_profile

        self.options = options
        self.robot = options.robot
        self.profile = load_profile(options.profile_path)
        self.experiment = load_experiment(options.experiment_path)
        self.entry = self.experiment.robot(options.robot)
        check_gaze(
            options.experiment_path,
            self.experiment,
            self.profile,
            sim=options.sim_scene is not None,
        )
        self.settings: DaemonSettings = self.experiment.daemon
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._rate = _Rate()
        self._cpu = _Cpu()
        self._peer_inbox: DropOldest[tuple[float, Any]] = DropOldest(self.settings.inbox)
        self._frames = 0
        self._old_joint_frames = 0
        self._frames_without_joints = 0
        self._last_frame = time.monotonic()
        self._last_world_sent = -math.inf
        self._calibration = "not started"
        self._ready = False
        self._faults_logged: set[str] = set()
        self._dropped = _Growth(window=2.0)
        self._presence = _Presence(self.experiment.peers.stale_after)
        self._search: _MarkerSearch | None = None
        self.devices: Any = None
        self.pipeline: Any = None
        self.link: Any = None
        self.telemetry: Any = None
        self.view: Any = None
        self.games: Any = None
        self.gaze: Gaze | None = None
        self._world: Any = None
        self.error: str | None = None

    # -- life cycle -------------------------------------------------------------------------------

    def start(self) -> None:
        """Open the network, the devices and the outputs, and start the threads."""
        from percept.runtime.daemon.devices import open_devices
        from percept.runtime.record.recording import Telemetry

        self.telemetry = Telemetry(raw_images=self.options.raw_images)
        if self.options.record is not None:
            self.telemetry.record(self.options.record, metadata=self._metadata())
        if self.options.view_port is not None:
            from percept.runtime.record.view import LiveView

            self.view = LiveView(self.telemetry, self.robot, self.options.view_port)
        self.link = self._open_link()
        self.devices = open_devices(
            self.robot,
            self.profile,
            self.experiment,
            sim_scene=self.options.sim_scene,
            sim_epoch=self.options.sim_epoch,
        )
        self.devices.start()
        self.gaze = self._open_gaze()
        self._spawn("perception", self._perception_loop)
        self._spawn("publisher", self._publisher_loop)

    def run(self, stop: threading.Event) -> int:
        """Start, wait for ``stop`` (set by a signal handler), stop; the exit code."""
        try:
            self.start()
            while not stop.wait(0.2):
                if self._stop.is_set():  # a thread gave up (e.g. calibration impossible)
                    break
        finally:
            self.stop()
        return 1 if self.error else 0

    def stop(self) -> None:
        """Stop every thread and device; the recording is closed first. Idempotent."""
        began = time.monotonic()
        self._stop.set()
        for thread in self._threads:
            thread.join(max(0.05, 0.8 - (time.monotonic() - began)))
        if self.telemetry is not None:
            self.telemetry.close()
        for closer in (self.view, self.devices, self.link):
            if closer is None:
                continue
            try:
                closer.close()
            except Exception as err:  # shutting down: say it, keep closing the rest
                log.warning("closing %s failed: %s", type(closer).__name__, err)
        self.view = self.devices = self.link = None
        log.info("stopped in %.2f s", time.monotonic() - began)

    def _open_gaze(self) -> Gaze | None:
        """Gaze over the servo bus when the experiment enables it (nothing moves until asked)."""
        from percept.drivers.dynamixel.bus import DynamixelBus
        from percept.kinematics.tree import KinematicTree
        from percept.runtime.daemon.gaze import Gaze

        joints = self.devices.joints
        if not self.experiment.gaze.enabled or not isinstance(joints, DynamixelBus):
            return None
        tree = KinematicTree.from_settings(self.profile.kinematics)
        return Gaze(joints, tree, self.profile.joints, self.experiment.gaze)

    def _spawn(self, name: str, target: Any) -> None:
        thread = threading.Thread(target=self._guard, args=(name, target), name=name, daemon=True)
        self._threads.append(thread)
        thread.start()

    def _guard(self, name: str, target: Any) -> None:
        try:
            target()
        except Exception as err:
            self.error = f"{name} thread failed: {err}"
            log.exception("%s thread failed", name)
            self._stop.set()

    def _open_link(self) -> Any:
        from percept.runtime.daemon.pipeline import alive_event
        from percept.runtime.games.pointing import PointingGames, located
        from percept.runtime.net.link import Link

        link = Link(self.experiment, self.robot)
        peers = {r.name for r in self.experiment.robots} - {self.robot}

        def on_boxes(message: Any) -> None:
            # Only the experiment's robots are peers: another sender would stay "not heard"
            # for ever once it stops.
            if message.robot in peers:
                self._presence.heard(message.robot)
                self._peer_inbox.put((time.monotonic(), message.to_json()))

        def on_alive(name: str, alive: bool) -> None:
            # A peer that exits is gone at once, not stale_after later; through the inbox, so
            # the frames (and a replay) see it at the same point.
            if not alive:
                self._presence.gone(name)
            self._peer_inbox.put((time.monotonic(), alive_event(name, alive)))

        link.subscribe("boxes", on_boxes)
        link.watch_alive(on_alive)
        self.games = PointingGames(
            link,
            world=lambda: [] if self._world is None else located(self._world),
            poses=lambda peer: (
                None if self.pipeline is None else self.pipeline.peers.tracker.pose(peer)
            ),
            settings=self.experiment.peers,
        )
        return link

    def _metadata(self) -> dict[str, str]:
        return {
            "robot": self.robot,
            "profile": str(Path(self.options.profile_path).resolve()),
            "experiment": str(Path(self.options.experiment_path).resolve()),
            "sim_scene": self.options.sim_scene or "",
            "started": f"{time.time():.6f}",
        }

    # -- perception thread ------------------------------------------------------------------------

    def _prepare_background(self, camera: Any) -> bool:
        """Load the background model, or calibrate it on the next frames (progress logged)."""
        path = self.options.background
        if path is not None and Path(path).exists():
            self.pipeline.load_background(path)
            self._calibration = f"loaded {path}"
            log.info("background loaded from %s", path)
            return True
        needed = self.pipeline.calibration_frames
        self._calibration = f"calibrating 0/{needed}"
        log.info("calibrating the background on %d frames: keep the scene empty", needed)

        def frames() -> Iterator[Any]:
            # Streamed into the calibration as they come: no list of frames held meanwhile.
            while True:
                if self._stop.is_set():
                    raise _Stopped
                frame = camera.wait(timeout=0.5)
                if frame is not None:
                    yield frame.image

        def progress(done: int, total: int) -> None:
            self._calibration = f"calibrating {done}/{total}"
            if done % max(1, total // 5) == 0 or done == total:
                log.info("background calibration %d/%d frames", done, total)

        try:
            with self.devices.calibration():
                self.pipeline.calibrate(frames(), progress)
        except _Stopped:
            return False
        self._calibration = f"calibrated on {needed} frames"
        if path is not None:
            self.pipeline.save_background(path)
            log.info("background saved to %s", path)
        self.telemetry.attach_background(self.pipeline)
        return True

    def _perception_loop(self) -> None:
        from percept.runtime.daemon.pipeline import FrameInputs, Pipeline

        camera, joints = self.devices.camera, self.devices.joints
        width, height = self.devices.resolution
        self.pipeline = Pipeline(
            self.robot,
            self.profile,
            self.experiment,
            width,
            height,
            joint_max_age=self.settings.joint_max_age,
        )
        if not self._prepare_background(camera):
            return
        search = self._search = _MarkerSearch(self.pipeline.boxes.detector.detect, self._stop)
        self._spawn("markers", search.run)
        every = self.experiment.landmarks.every
        since_search = every  # the first frame is searched
        self._ready = True
        self._last_frame = time.monotonic()
        while not self._stop.is_set():
            frame = camera.wait(timeout=0.2)
            if frame is None:
                continue
            began = time.monotonic()
            self._last_frame = began
            sample = joints.angles_at(frame.t)
            if sample is None:  # no joint reading yet: no camera pose, nothing to publish
                self._frames_without_joints += 1
                continue
            found = search.finished()
            inputs = FrameInputs(
                seq=frame.seq,
                t=frame.t,
                wall=frame.wall,
                joints=sample.angles,
                joint_age=_finite(sample.age),
                stale_joints=tuple(sorted(sample.stale)),
                peer_messages=tuple(self._peer_inbox.drain()),
                marker_frames=tuple(found),
            )
            out = self.pipeline.step(frame.image, inputs, found)
            since_search += 1
            if (
                since_search >= every
                and out.pose is not None
                and search.take(frame.seq, frame.image)
            ):
                since_search = 0
            self._frames += 1
            if out.pose is None or not out.pose.fresh:
                self._old_joint_frames += 1
            self._publish_world(out.world, began)
            self.telemetry.log_frame(inputs.record(), frame.image)
            if out.pose is not None:
                self.telemetry.log_pose(frame.wall, out.pose.pose.R, out.pose.pose.t)
            self.telemetry.log_world(out.world, frame.wall)
            if self.view is not None:
                self.view.update(frame, out)
            self._rate.add(time.monotonic(), time.monotonic() - began)

    def _publish_world(self, world: dict[str, Any], now: float) -> None:
        from percept.runtime.net.messages import World

        self._world = World.from_json(world, "world")
        rate = self.settings.world_rate
        if rate > 0 and now - self._last_world_sent < 1.0 / rate:
            return
        self._last_world_sent = now
        self.link.publish("world", self._world)

    # -- publisher thread -------------------------------------------------------------------------

    def _publisher_loop(self) -> None:
        """Box poses at the box rate; the status every ``status_interval`` and at once when the
        faults change (looked at every :data:`FAULT_CHECK` seconds)."""
        from percept.runtime.net.messages import Boxes

        box_interval = 1.0 / self.experiment.peers.box_rate
        next_boxes = next_status = next_check = time.monotonic()
        published: set[str] = set()
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_boxes:
                next_boxes = max(next_boxes + box_interval, now)
                if self.pipeline is not None:
                    message = Boxes(self.robot, time.time(), tuple(self.pipeline.boxes.boxes(now)))
                    self.link.publish("boxes", message)
                    self.telemetry.log_boxes({"schema": Boxes.SCHEMA, **message.to_json()})
            if now >= next_check:
                next_check = now + FAULT_CHECK
                if set(self.faults()) != published:
                    next_status = now
            if now >= next_status:
                next_status = max(next_status + self.settings.status_interval, now)
                status = self.status()
                self.link.publish("status", status)
                self.telemetry.log_status(status)
                self._log_faults(status["faults"])
                published = set(status["faults"])
            wake = min(next_boxes, next_status, next_check)
            self._stop.wait(max(0.0, wake - time.monotonic()))

    def status(self) -> dict[str, Any]:
        """The ``percept.status/1`` message: rates, driver states, peers, faults in words."""
        from percept.runtime.net.messages import Status

        now = time.monotonic()
        camera = self.devices.camera.status() if self.devices else {"state": "stopped"}
        servos = self.devices.joints.status() if self.devices else {"state": "stopped"}
        peers = self._presence.status(now)
        recording = self.telemetry.recording() if self.telemetry is not None else None
        faults = self._faults(now, camera, servos, peers, recording)
        rejected = self.link.rejected if self.link is not None else 0
        games = self.games.results if self.games is not None else []
        gaze = self._gaze_status()
        return {
            "schema": Status.SCHEMA,
            "robot": self.robot,
            "stamp": time.time(),
            "fps": round(self._rate.fps(), 2),
            "ms_per_frame": self._rate.ms_median(),
            "frames": self._frames,
            "dropped_frames": int(camera.get("dropped", 0)),
            "old_joint_frames": self._old_joint_frames,
            "frames_without_joints": self._frames_without_joints,
            "camera": camera,
            "servos": servos,
            "background": self._calibration,
            "peers": peers,
            "rejected_messages": rejected,
            "inbox_dropped": self._peer_inbox.dropped,
            "games": {
                "played": len(games),
                "success": sum(g.outcome == "success" for g in games),
                "as_speaker": sum(g.role == "speaker" for g in games),
            },
            "cpu": self._cpu.sample(),
            "rss_mb": resident_mb(),
            "recording": recording,
            "gaze": gaze,
            "faults": faults,
        }

    def _gaze_status(self) -> dict[str, Any]:
        if self.gaze is not None:
            return self.gaze.status()
        return {"enabled": self.experiment.gaze.enabled, "state": "off", "target": None}

    def faults(self) -> list[str]:
        """What is wrong now, in words (the status's ``faults``)."""
        now = time.monotonic()
        return self._faults(
            now,
            self.devices.camera.status() if self.devices else {"state": "stopped"},
            self.devices.joints.status() if self.devices else {"state": "stopped"},
            self._presence.status(now),
            self.telemetry.recording() if self.telemetry is not None else None,
        )

    def _faults(
        self,
        now: float,
        camera: dict[str, Any],
        servos: dict[str, Any],
        peers: dict[str, Any],
        recording: dict[str, Any] | None,
    ) -> list[str]:
        # Each fault's words stay the same while it lasts: a change publishes the status at once
        # and is logged.
        faults: list[str] = []
        if camera.get("state") != "connected":
            faults.append(f"camera {camera.get('state')}" + _because(camera.get("error")))
        if servos.get("state") != "connected":
            faults.append(f"servos {servos.get('state')}" + _because(servos.get("problem")))
        silent = servos.get("not_answering") or {}
        for joint in servos.get("stale") or ():
            faults.append(f"joint {joint} stale" + _because(silent.get(joint)))
        for joint, errors in sorted((servos.get("errors") or {}).items()):
            faults.append(f"servo {joint} reports {', '.join(errors)}")
        gaze = servos.get("gaze") or {}
        if gaze.get("state") == "stopped":
            faults.append(f"gaze stopped: {gaze.get('problem')}")
        if not self._ready:
            faults.append("no background model yet")  # the progress is in "background"
        elif now - self._last_frame > self.settings.frame_timeout:
            faults.append(f"no frame for more than {self.settings.frame_timeout:g} s")
        for name, peer in sorted(peers.items()):
            if not peer.get("heard"):
                faults.append(f"peer {name} not heard")
        if recording is not None and recording["state"] != "recording":
            faults.append(
                f"recording {recording['state']}: {recording['error']} ({recording['file']}); "
                "goes on in a new file when the disk takes data again"
            )
        if self.link is not None:
            for key, traffic in sorted(self.link.traffic().items()):
                if traffic.rejected:
                    faults.append(f"rejecting messages on {key}: {traffic.reason}")
                if traffic.rate > self.settings.flood_rate:
                    faults.append(
                        f"flood on {key}: more than {self.settings.flood_rate:g} messages/s"
                    )
            dropped = self.link.dropped + self._peer_inbox.dropped
            if self._dropped.grew(dropped, now):
                faults.append("dropping received messages: they come faster than handled")
        return _bounded(faults)

    def _log_faults(self, faults: list[str]) -> None:
        """Log each fault when it appears and when it clears, not every second."""
        current = set(faults)
        for fault in sorted(current - self._faults_logged):
            log.warning("fault: %s", fault)
        for fault in sorted(self._faults_logged - current):
            log.info("cleared: %s", fault)
        self._faults_logged = current


class _Presence:
    """When each peer robot was last heard from (on the link's thread, whatever the frames do),
    and whether it left (its liveliness token went): the status's ``peers``."""

    def __init__(self, stale_after: float) -> None:
        self.stale_after = stale_after
        self._heard: dict[str, float] = {}
        self._lock = threading.Lock()

    def heard(self, name: str) -> None:
        with self._lock:
            self._heard[name] = time.monotonic()

    def gone(self, name: str) -> None:
        with self._lock:
            if name in self._heard:
                self._heard[name] = -math.inf

    def status(self, now: float) -> dict[str, Any]:
        with self._lock:
            heard = list(self._heard.items())
        return {
            name: {"heard": now - last < self.stale_after, "age": _finite(now - last)}
            for name, last in heard
        }


class _Growth:
    """Whether a counter grew within the last ``window`` seconds."""

    def __init__(self, window: float) -> None:
        self.window = window
        self._value = 0
        self._when = -math.inf

    def grew(self, value: int, now: float) -> bool:
        if value > self._value:
            self._value, self._when = value, now
        return now - self._when <= self.window


class _MarkerSearch:
    """The marker search of one frame at a time, on a thread of its own (:meth:`run`).

    :meth:`take` hands it a frame if it is idle; :meth:`finished` gives the markers of the
    frames searched since the last call, by frame ``seq``, in the order they were taken.
    """

    def __init__(self, detect: Any, stop: threading.Event) -> None:
        self._detect = detect
        self._stop = stop
        self._cond = threading.Condition()
        self._job: tuple[int, Any] | None = None
        self._busy = False
        self._done: dict[int, list[Any]] = {}

    def take(self, seq: int, image: Any) -> bool:
        """Search frame ``seq`` unless a search is under way; whether it was taken."""
        with self._cond:
            if self._busy:
                return False
            self._job, self._busy = (seq, image), True
            self._cond.notify()
            return True

    def finished(self) -> dict[int, list[Any]]:
        with self._cond:
            done, self._done = self._done, {}
            return done

    def run(self) -> None:
        while not self._stop.is_set():
            with self._cond:
                if self._job is None:
                    self._cond.wait(0.2)
                    continue
                seq, image = self._job
                self._job = None
            markers = self._detect(image)
            with self._cond:
                self._done[seq] = markers
                self._busy = False


class _Stopped(Exception):
    """Stopped while calibrating the background."""


def _bounded(faults: list[str]) -> list[str]:
    """At most ``MAX_FAULTS`` faults of at most :data:`FAULT_WORDS` characters: the status must
    stay a valid message whatever keys and payloads a babbling sender makes up."""
    from percept.runtime.net.messages import MAX_FAULTS

    short = [f if len(f) <= FAULT_WORDS else f[: FAULT_WORDS - 3] + "..." for f in faults]
    if len(short) > MAX_FAULTS:
        short = [*short[: MAX_FAULTS - 1], "more faults than shown"]
    return short


def _because(error: str | None) -> str:
    return f" ({error})" if error else ""
