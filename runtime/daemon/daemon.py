"""The onboard daemon: one process per robot, from camera and servos to the network.

Threads (SPEC §2):

- the camera's reader thread and the servo bus's reader thread (inside the drivers; each keeps
  only fresh data, reconnects by itself and reports its state),
- in simulation, the simulated world's thread that feeds the servo emulator,
- ``perception``: takes the newest frame, the joint angles at its time and the peer messages
  that arrived since the last frame, runs the :class:`~percept.runtime.daemon.pipeline.Pipeline`,
  publishes the world model and logs it (recording, live view)
  (:mod:`percept.runtime.daemon.perceiving`),
- ``markers``: the marker search on every ``[landmarks] every``-th frame (or the next one when
  it is still busy; of the whole image, or of windows following the markers found before, see
  :mod:`percept.perception.landmarks.follow`), whose result the perception thread applies at the
  next frame: the search (at 640x480 about 9 ms of the whole image, 5 ms following) does not
  hold up the world models of the frames meanwhile,
- ``publisher``: the robot's box poses at 5 Hz and its status at 1 Hz
  (:mod:`percept.runtime.daemon.publishing`),
- the games' threads: a game the monitor starts is played on a thread of its own, and with gaze a
  hearer's look too (:mod:`percept.runtime.games.looking`; the games look only once the
  background is calibrated, the sweep over),
- Zenoh's own threads, whose callbacks only put messages into bounded queues.

``percept run``'s main thread waits for SIGINT or SIGTERM, and then everything stops within
two seconds, recording first (:mod:`percept.runtime.daemon.stopping`).

Nothing that passed validation may stop the daemon: its own outgoing messages (world, boxes,
status) are checked before they go, and one that fails is not sent but logged, counted
(``unsent_messages``) and reported in the status's faults while the frames go on
(:class:`~percept.runtime.daemon.publishing.Outbox`); peer data that
the schema accepts but the experiment's arena does not is rejected and reported by sender
(:mod:`percept.runtime.net.peers`); and a second process under this robot's name is refused at
start, or reported by both when the two meet later (:class:`percept.runtime.net.link.Link`'s
``exclusive``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from percept.runtime.daemon.calibration import BackgroundStart
from percept.runtime.daemon.network import games_look, hear_peers, open_games, open_link
from percept.runtime.daemon.perceiving import Outputs, PerceptionThread
from percept.runtime.daemon.publishing import Outbox, Publisher
from percept.runtime.daemon.settings import DaemonOptions, DaemonSettings, load_run
from percept.runtime.daemon.status import health
from percept.runtime.daemon.status.faults import (
    device_faults,
    frame_faults,
    marker_faults,
    network_faults,
    peer_faults,
    recording_faults,
)
from percept.runtime.net.mailbox import DropOldest
from percept.runtime.net.messages import clip
from percept.runtime.ros2 import open_ros2

if TYPE_CHECKING:
    from percept.runtime.daemon.devices import Devices
    from percept.runtime.daemon.gaze import Gaze
    from percept.runtime.daemon.pipeline import PeerMessage, Pipeline
    from percept.runtime.games.language.live import GuessingGames
    from percept.runtime.games.pointing import PointingGames
    from percept.runtime.incidents import Run
    from percept.runtime.net.codec import JSON
    from percept.runtime.net.link import Link
    from percept.runtime.net.messages import PeerPose, Status, World
    from percept.runtime.record.telemetry import Telemetry
    from percept.runtime.record.view import LiveView
    from percept.runtime.ros2.publisher import Ros2Publisher

log = logging.getLogger("percept.daemon")


class Daemon:
    """One robot's onboard process; see the module doc for its threads."""

    def __init__(self, options: DaemonOptions) -> None:
        self.options = options
        self.robot = options.robot
        self.profile, self.experiment = load_run(options)
        self.entry = self.experiment.robot(options.robot)
        self.settings: DaemonSettings = self.experiment.daemon
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._cpu = health.Cpu()
        self._peer_inbox: DropOldest[tuple[float, PeerMessage]] = DropOldest(self.settings.inbox)
        background = None if options.background is None else Path(options.background)
        self.perceiving = PerceptionThread(
            self.robot,
            self.profile,
            self.experiment,
            BackgroundStart(background, self.profile.camera.joint_delay, self._stop),
            self._peer_inbox,
            self._stop,
        )
        self._dropped = health.Growth(window=2.0)
        self._ambiguous = health.Growth(window=2.0)
        self._presence = health.Presence(self.experiment.peers.stale_after)
        # Opened by start() before the threads run, closed by stop().
        self.devices: Devices | None = None
        self.link: Link | None = None
        self.outbox: Outbox | None = None
        self.publisher: Publisher | None = None
        self.telemetry: Telemetry | None = None
        self.view: LiveView | None = None
        self.games: PointingGames | None = None
        self.guessing: GuessingGames | None = None
        self.gaze: Gaze | None = None
        self.ros2: Ros2Publisher | None = None  # with [ros2] enabled only
        self.error: str | None = None
        self._began = time.monotonic()
        self._last_faults: list[str] | None = None  # as the run's wait ended

    # -- life cycle -------------------------------------------------------------------------------

    def start(self) -> None:
        """Open the network, the devices and the outputs, and start the threads."""
        import cv2

        from percept.kinematics.camera import CameraModel
        from percept.runtime.daemon.devices import open_devices

        # OpenCV on one thread: its pool's worker waits for the next parallel call spinning in
        # sched_yield, a third of its time (folder-640: 4.3 % of a core, the status's "other",
        # for a split of OpenCV's calls that the daemon's own threads do not need).
        cv2.setNumThreads(1)
        options = self.options
        # Only a run that records or is watched logs anything: without either, foxglove-sdk
        # (11 MB of the daemon's memory) is not even imported.
        telemetry = None
        if options.record is not None or options.view_port is not None:
            from percept.runtime.record.telemetry import Telemetry

            telemetry = self.telemetry = Telemetry(raw_images=options.raw_images)
        # The network first: a daemon refused its name (NameTaken) or its port exits before it
        # touches anything else.
        self.link = self._open_link()
        self.outbox = Outbox(self.link, self.settings.world_rate)
        if telemetry is not None and options.view_port is not None:
            from percept.runtime.record.view import LiveView

            self.view = LiveView(telemetry, self.robot, options.view_port)
        devices = self.devices = open_devices(
            self.robot,
            self.profile,
            self.experiment,
            sim_scene=self.options.sim_scene,
            sim_epoch=self.options.sim_epoch,
        )
        devices.start()
        self.gaze = self._open_gaze(devices)
        lens = self.profile.camera.lens
        camera = CameraModel.from_lens(lens, *devices.resolution)
        self.ros2 = open_ros2(self.experiment.ros2, self.robot, camera)
        # The recording is created last, when nothing else can fail (a port in use): a daemon
        # that cannot start leaves no file behind.
        if telemetry is not None and options.record is not None:
            try:
                telemetry.record(options.record, metadata=self._metadata())
            except OSError as err:  # percept run checked the folder: it changed since
                from percept.config.loader import ConfigError

                why = err.strerror or str(err)
                raise ConfigError("--record", str(options.record), why) from None
        outputs = Outputs(self.outbox, telemetry, self.view, self.ros2)
        perceiving, gaze = self.perceiving, self.gaze
        self._spawn(
            "perception",
            lambda: perceiving.run(devices, outputs, gaze, self._spawn, self._let_games_look),
        )
        self.publisher = Publisher(
            self.robot,
            self.outbox,
            telemetry,
            lambda now: None if self.pipeline is None else self.pipeline.boxes.boxes(now),
            self.status,
            self.faults,
            lambda: perceiving.background.phase,
            self.experiment.peers.box_rate,
            self.settings.status_interval,
            self._stop,
        )
        self._spawn("publisher", self.publisher.run)

    def run(self, stop: threading.Event) -> int:
        """Start, wait for ``stop`` (set by a signal handler), stop; the exit code."""
        try:
            self.start()
            while not stop.wait(0.2):
                if self._stop.is_set():  # a thread gave up (e.g. calibration impossible)
                    break
            self._last_faults = self.faults()  # while the devices still say what they lack
        finally:
            self.stop()
        if self.error:
            return 1
        if self.perceiving.frames == 0:
            self.say_no_world_model()
            return 1
        return 0

    def say_no_world_model(self) -> None:
        """Log why this run made no world model: one that made none has failed, whatever
        stopped it (``percept run`` says it too when the stop does not finish in time)."""
        faults = self._last_faults
        if faults is None:
            try:
                faults = self.faults()
            except Exception as err:  # the devices closing under it: say that instead
                faults = [f"not known ({err})"]
        log.error(
            "no frame processed in %.0f s (%d frames had no joint readings); last faults: %s",
            time.monotonic() - self._began,
            self.perceiving.without_joints,
            "; ".join(faults) or "none",
        )

    @property
    def frames(self) -> int:
        """Frames made into world models so far (0: the run has not made one)."""
        return self.perceiving.frames

    @property
    def pipeline(self) -> Pipeline | None:
        """The perception thread's pipeline (None before the thread began)."""
        return self.perceiving.pipeline

    def stop(self) -> None:
        """Stop every thread and device; the recording is closed first. Idempotent."""
        began = time.monotonic()
        self._stop.set()
        for thread in self._threads:
            # 0.5 s for all: the devices' close (the servos' torque policy) must come well
            # inside percept run's grace (stopping.GRACE), whatever a thread is stuck in.
            thread.join(max(0.05, 0.5 - (time.monotonic() - began)))
        if self.telemetry is not None:
            self.telemetry.close()
        # The devices first: their close applies the servos' torque policy, which must not wait
        # behind a network session's.
        closers: tuple[LiveView | Devices | Link | Ros2Publisher | None, ...] = (
            self.view,
            self.devices,
            self.ros2,
            self.link,
        )
        for closer in closers:
            if closer is None:
                continue
            try:
                closer.close()
            except Exception as err:  # shutting down: say it, keep closing the rest
                log.warning("closing %s failed: %s", type(closer).__name__, err)
        self.view = self.devices = self.link = self.ros2 = None
        log.info("stopped in %.2f s", time.monotonic() - began)

    def latest(self) -> tuple[Status | None, World | None]:
        """The status last published and the last world model (None before the first): what
        the console shows."""
        return (None if self.publisher is None else self.publisher.published), self.perceiving.world

    def _open_gaze(self, devices: Devices) -> Gaze | None:
        """Gaze over the servo bus when the experiment enables it (nothing moves until asked)."""
        from percept.drivers.dynamixel.bus import DynamixelBus
        from percept.kinematics.tree import KinematicTree
        from percept.runtime.daemon.gaze import Gaze

        joints = devices.joints
        if not self.experiment.gaze.enabled or not isinstance(joints, DynamixelBus):
            return None
        tree = KinematicTree.from_settings(self.profile.kinematics)
        return Gaze(joints, tree, self.profile.joints, self.experiment.gaze)

    def _let_games_look(self) -> None:
        """With gaze, the pointing games turn the head from now on (the calibration sweep is
        over), waiting for the frames this loop finishes; unless ``[peers] network_gaze`` keeps
        games from the network from turning it here."""
        from percept.runtime.games.looking import Looker

        if self.gaze is None or self.games is None:
            return
        if not games_look(self.experiment):
            log.warning(
                'games from the network do not turn the head: [peers] network_gaze = "lab" '
                "and this is not the lab deployment (%s)",
                self.experiment.network.trust(self.link.listen if self.link else []),
            )
            return
        self.games.looker = Looker(self.gaze, lambda: self.perceiving.progress, self._stop)

    def _spawn(self, name: str, target: Callable[[], None]) -> None:
        thread = threading.Thread(target=self._guard, args=(name, target), name=name, daemon=True)
        self._threads.append(thread)
        thread.start()

    def _guard(self, name: str, target: Callable[[], None]) -> None:
        try:
            target()
        except Exception as err:
            if self._stop.is_set():
                # What a stop closed under a thread (the link, the camera, the recording) ends
                # it with an error: the end of the stop, not a failure.
                log.info("%s thread ended by the stop: %s", name, err)
                log.debug("%s thread's end", name, exc_info=True)
                return
            self.error = f"{name} thread failed: {err}"
            log.exception("%s thread failed", name)
            self._stop.set()

    def _open_link(self) -> Link:
        """The link, listening to the peers, and the games played on it."""
        options = self.options
        endpoints = options.endpoints
        link = open_link(self.experiment, self.robot, options.experiment_path, endpoints)
        peers = {r.name for r in self.experiment.robots} - {self.robot}
        hear_peers(link, peers, self._presence, self._peer_inbox)

        def poses(peer: str) -> PeerPose | None:
            return None if self.pipeline is None else self.pipeline.peers.tracker.pose(peer)

        def world() -> World | None:
            return self.perceiving.world

        self.games, self.guessing = open_games(link, self.experiment, world, poses)
        return link

    def _metadata(self) -> dict[str, str]:
        """What a replay needs to find the files again, from any folder: shipped files by name,
        the others by absolute path."""
        from percept.config import portable_name

        options = self.options
        scene = options.sim_scene
        return {
            "robot": self.robot,
            "profile": portable_name("robots", options.profile_path),
            "experiment": portable_name("experiments", options.experiment_path),
            "sim_scene": "" if scene is None else portable_name("scenes", scene),
            "started": f"{time.time():.6f}",
        }

    # -- status -----------------------------------------------------------------------------------

    def status(self) -> Status:
        """The ``percept.status/1`` message: rates, driver states, peers, faults in words."""
        from percept.runtime.net.messages import Status

        now = time.monotonic()
        camera = self.devices.camera.status() if self.devices else _stopped()
        servos = self.devices.joints.status() if self.devices else _stopped()
        peers = self._peer_status(now)
        recording = self.telemetry.recording() if self.telemetry is not None else None
        # one look at the light for both its field and its fault: the perception thread may
        # take a frame in between, and a status must not contradict itself
        light = self._light_status()
        faults = self._faults(now, camera, servos, peers, recording, light)
        rejected = self.link.rejected if self.link is not None else 0
        games, guessing = self.games, self.guessing
        gaze = self._gaze_status()
        unsent = self.outbox.unsent() if self.outbox is not None else 0
        unsent += guessing.unsent if guessing else 0
        cpu, threads = self._cpu.sample()
        perceiving = self.perceiving
        return Status(
            robot=self.robot,
            stamp=time.time(),
            fps=round(perceiving.rate.fps(), 2),
            ms_per_frame=perceiving.rate.ms_median(),
            frames=perceiving.frames,
            dropped_frames=int(camera.get("dropped", 0)),
            old_joint_frames=perceiving.old_joint_frames,
            frames_without_joints=perceiving.without_joints,
            camera=camera,
            servos=servos,
            background=clip(perceiving.background.state),
            background_unknown=perceiving.unknown,
            peers=dict(peers),  # as JSON: to the checker a dict of dicts is no dict of JSON
            rejected_messages=rejected,
            inbox_dropped=self._peer_inbox.dropped,
            games={
                "played": games.played if games else 0,
                "success": games.won if games else 0,
                "as_speaker": games.as_speaker if games else 0,
                "ignored": sum(games.ignored.values()) if games else 0,
                "guessing_played": guessing.played if guessing else 0,
                "guessing_success": guessing.won if guessing else 0,
                "guessing_as_speaker": guessing.as_speaker if guessing else 0,
                "guessing_ignored": sum(guessing.ignored.values()) if guessing else 0,
                "lexicon_size": guessing.lexicon_size if guessing else 0,
                "categories": guessing.categories if guessing else 0,
            },
            cpu=cpu,
            cpu_threads=threads,
            rss_mb=health.resident_mb(),
            recording=recording,
            unsent_messages=unsent,
            ambiguous_markers=self.pipeline.boxes.ambiguities if self.pipeline else 0,
            gaze=gaze,
            light=light,
            network=self._network_status(),
            faults=tuple(faults),
        )

    def _light_status(self) -> dict[str, Any] | None:  # LightStatus.as_dict(): JSON-able
        """The light as the background sees it (None before calibration or when off)."""
        light = self.pipeline.perception.light if self.pipeline is not None else None
        return None if light is None else light.status.as_dict()

    def _network_status(self) -> dict[str, JSON]:
        """How the robot meets the others, and whom that lets speak as a player."""
        network = self.experiment.network
        listen = self.link.listen if self.link is not None else []
        return {
            "mode": network.mode,
            "trust": network.trust(listen),
            "games_look": games_look(self.experiment),
        }

    def _gaze_status(self) -> dict[str, JSON]:
        if self.gaze is not None:
            return self.gaze.status()
        return {"enabled": self.experiment.gaze.enabled, "state": "off", "target": None}

    def faults(self) -> list[str]:
        """What is wrong now, in words (the status's ``faults``)."""
        now = time.monotonic()
        return self._faults(
            now,
            self.devices.camera.status() if self.devices else _stopped(),
            self.devices.joints.status() if self.devices else _stopped(),
            self._peer_status(now),
            self.telemetry.recording() if self.telemetry is not None else None,
            self._light_status(),
        )

    def _peer_status(self, now: float) -> dict[str, dict[str, JSON]]:
        """The status's ``peers``: heard, age and, once there was any, ``implausible`` (how many
        of its box messages or poses the arena gate rejected)."""
        peers = self._presence.status(now)
        for name, run in self._implausible().items():
            peers.setdefault(name, {"heard": False, "age": None})["implausible"] = run.total
        return peers

    def _implausible(self) -> dict[str, Run]:
        return {} if self.pipeline is None else self.pipeline.peers.tracker.implausible()

    def _faults(
        self,
        now: float,
        camera: dict[str, Any],  # the drivers' status(), typed by them
        servos: dict[str, Any],
        peers: Mapping[str, Mapping[str, JSON]],
        recording: Mapping[str, JSON] | None,
        light: Mapping[str, Any] | None,
    ) -> list[str]:
        emulated = self.devices is not None and self.devices.emulated_servos
        out = device_faults(camera, servos, emulated)
        since_frame = now - self.perceiving.last_frame
        out += frame_faults(self.perceiving.ready, since_frame, self.settings.frame_timeout, light)
        boxes = self.pipeline.boxes if self.pipeline is not None else None
        if boxes is not None and self._ambiguous.grew(boxes.ambiguities, now):
            out += marker_faults(boxes.ambiguous_ids)
        out += peer_faults(peers, self._implausible(), now)
        if self.outbox is not None:
            out += self.outbox.faults(now)
        out += recording_faults(recording, time.time())
        link = self.link
        if link is not None:
            dropping = self._dropped.grew(link.dropped + self._peer_inbox.dropped, now)
            traffic = link.traffic()
            rate = self.settings.flood_rate
            out += network_faults(
                self.robot, bool(link.clashes), traffic, link.prefix, rate, dropping
            )
        return health.bounded(out)


def _stopped() -> dict[str, Any]:
    """A driver's status before start or after stop (typed as the drivers' ``status()``)."""
    return {"state": "stopped"}
