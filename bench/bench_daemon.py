"""Benchmark of the onboard daemon (issue 7's targets): capture -> world model on Zenoh latency,
CPU and resident memory of ``percept run``.

Each run starts ``percept run`` as robot a of the table-top experiment, its markers on every
k-th frame, in one of two modes:

- ``sim``: ``--sim SCENE``, the daemon renders its own camera (MuJoCo, software EGL here) and
  reads its servos through the Dynamixel emulator on a pty, all inside its own process: the
  CPU and memory include the simulated world's;
- ``folder``: the daemon as on a robot: frames from an image folder (JPEG, decoded by the
  camera driver at 30 fps like a USB camera's MJPEG) and its servos through ``percept
  emulate-servos``, a separate process standing in for the servo bus. The frames are the same
  scene, pre-rendered at 30 fps.

At 640x480 the scene is ``tabletop-myon`` (two MYON robots, ``config/robots/myon.toml``), at
320x200 ``tabletop-basic`` (two ROBOTIS OP3). The runs with the head moving (``sim-640-pan``,
issue 20) put the MYON robots into ``tabletop-pan`` (as ``bench_moving_head.py --myon`` does):
the head sweeps its working range for the background calibration, then pans back and forth at
0.12 rad/s the whole time while objects are put down; ``sim-640-pan-still`` is the same scene
with both heads held still, so that the two differ by the head's motion alone (the rendering
is in both). The daemon's perception ms per frame (its status) is reported beside the CPU.

``folder-640-pan`` is ``sim-640-pan`` without the rendering: robot a's view of that scene is
recorded once with ``percept sim`` (frames, and the joint angles at their times in
``joints.csv``), kept under ``--frames`` with its background (calibrated once, by a first
daemon, on the frames of the head's sweep), and served by the image folder and ``percept
emulate-servos --play`` from one wall-clock epoch (``[camera] epoch`` and ``--epoch``), so that
each frame is read when the servos say the angles it was rendered with. The window is measured
from the end of the sweep (``recording_s``); ``--skew`` puts the joints behind the frames.

A Zenoh client on the daemon's endpoint stamps each world model on arrival: latency is arrival
wall time minus the world's ``stamp`` (the frame's capture wall time; both clocks are this
machine's). The daemon's CPU time (all its
threads, from /proc) over the measured window gives its share of one core, and the mean of its
statuses' ``cpu_threads`` over the window how that share splits between its threads (the
camera's decoding, perception, the marker search, the servo bus, publishing; ``other``: Zenoh's
and the foxglove server's threads); its resident memory is read at the end (VmRSS, and the peak
VmHWM; ``rss_split_mb``: by mapped file from /proc/PID/smaps, grouped by library, and
``anonymous heap`` for memory no file backs). Start-up,
background calibration and the objects' arrival are not measured (``--warmup`` seconds after
calibration). ``--json`` prints only one JSON line per run.

``--startup`` times the start of ``percept run`` (robot a, ``--sim`` or as onboard with the
image folder and the emulated servos, the background loaded from a file that a first run
calibrated and saved): seconds from starting the process to its first world
model on Zenoh, with the compiled kernels' cache (``NUMBA_CACHE_DIR``, a fresh folder) empty (cold:
the kernels are compiled on the first frame) and then filled by that run and a completed warm-up
(warm; the cold run is stopped before its warm-up thread has compiled every kernel).

``--memory-stages`` reads the resident memory of a fresh interpreter after each stage of the
daemon's start (numpy and OpenCV, Zenoh, numba with LLVM, ``percept run``'s modules, numba's
first kernel, every kernel as the warm-up loads them), with the user's kernel cache: where the
memory comes from before the first frame, the anonymous heap included.

``--detector`` times only the marker search (``MarkerDetector.detect`` as configured by the
experiment, one thread) on the same pre-rendered frames at both sizes, against cv2.aruco's
AprilTag search over the whole image, and compares the corners the two find.

    python bench/bench_daemon.py [--seconds 15] [--runs folder-640,sim-640,...] [--detector]
    python bench/bench_daemon.py --runs folder-640-pan,folder-640 --seconds 20 --json
    python bench/bench_daemon.py --startup [--warm-only] [--runs folder-640,sim-320,sim-640]
    python bench/bench_daemon.py --memory-stages [--json]
"""

from __future__ import annotations

import argparse
import compileall
import json
import math
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.support.zenoh_rig import free_port  # noqa: E402

EXPERIMENT = ROOT / "config" / "experiments" / "tabletop.toml"
MYON = ROOT / "config" / "robots" / "myon.toml"
OP3 = ROOT / "config" / "robots" / "robotis-op3.toml"


@dataclass(frozen=True)
class Run:
    """One configuration of the daemon to measure."""

    mode: str  # "sim" or "folder"
    scene: str
    profile: Path
    every: int  # markers on every k-th frame
    head: str = "as in the scene"  # "pan", "still": tabletop-pan with MYON robots, see scene_file


RUNS = {
    "folder-640": Run("folder", "tabletop-myon", MYON, 3),
    "folder-640-pan": Run("folder", "tabletop-pan", MYON, 3, head="pan"),
    "folder-640-every1": Run("folder", "tabletop-myon", MYON, 1),
    "folder-640-every6": Run("folder", "tabletop-myon", MYON, 6),
    "folder-320": Run("folder", "tabletop-basic", OP3, 3),
    "sim-640": Run("sim", "tabletop-myon", MYON, 3),
    "sim-640-every1": Run("sim", "tabletop-myon", MYON, 1),
    "sim-320": Run("sim", "tabletop-basic", OP3, 3),
    "sim-640-pan": Run("sim", "tabletop-pan", MYON, 3, head="pan"),
    "sim-640-pan-still": Run("sim", "tabletop-pan", MYON, 3, head="still"),
}


def scene_file(run: Run, tmp: Path) -> str:
    """The scene ``run`` simulates: its name, or for a run with ``head`` set a copy of it with
    the robots of ``tabletop-myon`` (the heads' keyframes taken out for a still head)."""
    if run.head == "as in the scene":
        return run.scene
    from bench.bench_moving_head import myon_copy

    path = Path(myon_copy(run.scene, tmp))
    if run.head == "still":
        text = re.sub(
            r"^joints\.head_pan = .*$\n", "", path.read_text(encoding="utf-8"), flags=re.M
        )
        path.write_text(text, encoding="utf-8")
    return str(path)


def set_key(text: str, table: str, key: str, value: str) -> str:
    """``text`` (TOML) with ``key = value`` in ``[table]`` (replaced, or added to the table)."""
    start = text.index(f"[{table}]\n")
    end = text.find("\n[", start + 1)
    end = len(text) if end < 0 else end
    body = text[start:end]
    line = re.compile(rf"^{re.escape(key)}\s*=.*$", re.M)
    if line.search(body):
        body = line.sub(f"{key} = {value}", body, count=1)
    else:
        body = body.rstrip("\n") + f"\n{key} = {value}\n"
    return text[:start] + body + text[end:]


def experiment_for(
    tmp: Path, every: int, calibration_frames: int | None = None
) -> tuple[Path, str]:
    """The table-top experiment with free ports, absolute paths, markers every ``every`` frames
    (and the background calibrated on ``calibration_frames``, if given); robot a's endpoint."""
    text = EXPERIMENT.read_text(encoding="utf-8").replace('"../', f'"{EXPERIMENT.parent.parent}/')
    endpoints = {}
    for robot, port in (("a", "7447"), ("b", "7448")):
        endpoints[robot] = f"tcp/127.0.0.1:{free_port()}"
        text = text.replace(f"tcp/127.0.0.1:{port}", endpoints[robot])
    text = set_key(text, "landmarks", "every", str(every))
    if calibration_frames is not None:
        text += f"\n[perception.background]\ncalibration_frames = {calibration_frames}\n"
    path = tmp / "experiment.toml"
    path.write_text(text, encoding="utf-8")
    return path, endpoints["a"]


JPEG_QUALITY = 90


def render_frames(scene: str, out: Path, seconds: float, fps: float) -> dict[str, float]:
    """Robot a's camera in ``scene`` at ``fps`` for ``seconds``, as JPEG files in ``out`` (kept
    there for later runs with ``angles.json``, the still joint angles of its head)."""
    angles = out / "angles.json"
    if angles.is_file():
        return json.loads(angles.read_text(encoding="utf-8"))
    os.environ.setdefault("MUJOCO_GL", "egl")
    import cv2

    from percept.runtime.settings.scene import open_world

    out.mkdir(parents=True, exist_ok=True)
    world = open_world(scene)
    try:
        for k in range(round(seconds * fps)):
            image = world.render("a", k / fps)
            cv2.imwrite(str(out / f"{k:06d}.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        still = world.joint_angles("a", seconds)
    finally:
        world.close()
    angles.write_text(json.dumps(still), encoding="utf-8")  # last: marks the folder complete
    return still


@dataclass(frozen=True)
class Recording:
    """Robot a's moving-head run as ``percept sim`` recorded it: the frames (JPEG, in name
    order, 30 fps), the joint angles at their times (``joints.csv``), and how many first
    frames show the empty floor during the head's sweep (the background calibration's)."""

    frames: Path
    joints: Path
    calibration_frames: int


def record_run(run: Run, out: Path, seconds: float, fps: float) -> Recording:
    """``percept sim`` of robot a in ``run``'s scene (the MYON robots) into ``out``, its PNG
    frames turned into JPEG (as a USB camera's MJPEG), unless ``out`` holds it already."""
    import cv2

    from bench.bench_moving_head import myon_copy
    from percept.runtime.daemon.devices import head_sweep
    from percept.runtime.settings.scene import find_scene, load_scene

    out.mkdir(parents=True, exist_ok=True)
    scene = myon_copy(run.scene, out)
    # frames taken while the head sweeps the empty floor, less half a second: a frame or two
    # the daemon skips then does not bring objects into the background
    sweep = head_sweep(load_scene(find_scene(scene))[0], "a")
    recording = Recording(out / "frames", out / "joints.csv", round((sweep - 0.5) * fps))
    if (out / "complete").is_file():
        return recording
    sim = out / "sim"
    cmd = [sys.executable, "-m", "percept.runtime.cli", "sim", "--scene", scene, "--robot", "a"]
    cmd += ["--out", str(sim), "--seconds", f"{seconds:g}", "--fps", f"{fps:g}"]
    print(f"recording {seconds:g} s of {run.scene} (MYON) into {out} once", file=sys.stderr)
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    subprocess.run(cmd, cwd=ROOT, env=env, check=True, capture_output=True)
    recording.frames.mkdir(exist_ok=True)
    for png in sorted((sim / "img1").glob("*.png")):
        image = cv2.imread(str(png))
        jpeg = recording.frames / f"{png.stem}.jpg"
        cv2.imwrite(str(jpeg), image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        png.unlink()
    (sim / "joints.csv").replace(recording.joints)
    (out / "complete").write_text("", encoding="utf-8")
    return recording


def folder_profile(
    profile: Path, frames: Path, port: Path, tmp: Path, epoch: float | None = None
) -> Path:
    """``profile`` with its camera reading ``frames`` (the first at wall-clock ``epoch``, if
    given) and its servo bus on ``port``."""
    text = set_key(profile.read_text(encoding="utf-8"), "camera", "source", json.dumps(str(frames)))
    text = set_key(text, "bus", "port", json.dumps(str(port)))
    if epoch is not None:
        text = set_key(text, "camera", "epoch", repr(epoch))
    path = tmp / f"folder-{profile.name}"
    path.write_text(text, encoding="utf-8")
    return path


def start_emulator(
    profile: Path, port: Path, angles: dict[str, float], play: tuple[Path, float] | None = None
) -> subprocess.Popen:
    """``percept emulate-servos`` at ``port``: its joints at ``angles``, or playing back a
    recording (``play``: its joints.csv and the wall-clock epoch of its first row)."""
    cmd = [sys.executable, "-m", "percept.runtime.cli", "emulate-servos", "--robot", str(profile)]
    cmd += ["--link", str(port)] + [f"--set={j}={v}" for j, v in angles.items()]
    if play is not None:
        cmd += ["--play", str(play[0]), "--epoch", repr(play[1])]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    line = proc.stdout.readline()  # the port path, once the emulator is up
    if not line:
        raise RuntimeError("percept emulate-servos did not start")
    return proc


class Watcher:
    """A Zenoh client on the daemon's endpoint: world latencies and status messages."""

    def __init__(self, endpoint: str) -> None:
        import zenoh

        from percept.runtime.net.zenoh_config import config

        self.latencies: list[float] = []
        self.anchors: list[int] = []
        self.first_world: float | None = None
        """``time.monotonic()`` when the first world model arrived."""
        self.first_status_wall = math.inf
        """``time.time()`` when the first status arrived."""
        self.statuses: list[dict] = []
        self.measured: list[dict] = []
        """The statuses that arrived while :attr:`measuring`."""
        self._lock = threading.Lock()
        self.measuring = False
        # Opened after the daemon started: a client waits for its endpoint (30 s at most).
        settings = {
            "mode": "client",
            "connect": {"endpoints": [endpoint], "timeout_ms": 30000},
            "scouting": {"multicast": {"enabled": False}},
        }
        self.session = zenoh.open(config(settings))
        self.subs = [
            self.session.declare_subscriber("percept/a/world", self._on_world),
            self.session.declare_subscriber("percept/a/status", self._on_status),
        ]

    def _on_world(self, sample) -> None:
        now = time.time()
        if self.first_world is None:
            self.first_world = time.monotonic()
        if not self.measuring:
            return
        world = json.loads(sample.payload.to_bytes())
        with self._lock:
            self.latencies.append(now - world["stamp"])
            self.anchors.append(len(world["objects"]))

    def _on_status(self, sample) -> None:
        status = json.loads(sample.payload.to_bytes())
        with self._lock:
            self.first_status_wall = min(self.first_status_wall, time.time())
            self.statuses.append(status)
            if self.measuring:
                self.measured.append(status)

    def wait(self, predicate, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                if self.statuses and predicate(self.statuses[-1]):
                    return True
            time.sleep(0.2)
        return False

    def close(self) -> None:
        self.session.close()


def cpu_seconds(pid: int) -> float:
    from percept.runtime.daemon.status.health import TICKS_PER_S, cpu_ticks

    return cpu_ticks(f"/proc/{pid}/stat") / TICKS_PER_S


def memory_mb(pid: int) -> dict[str, float]:
    out = {}
    for line in Path(f"/proc/{pid}/status").read_text(encoding="utf-8").splitlines():
        key, _, value = line.partition(":")
        if key in ("VmRSS", "VmHWM", "RssAnon", "RssFile"):
            out[key] = int(value.split()[0]) / 1024
    return out


LIBRARIES = (
    # (group, substrings of a mapped file's path), the first that matches wins
    ("llvmlite", ("/llvmlite/",)),  # LLVM, which numba compiles and loads the kernels with
    ("numba", ("/numba/",)),
    ("cv2", ("/cv2/", "opencv")),
    ("scipy", ("/scipy/", "scipy.libs")),
    ("numpy", ("/numpy/", "numpy.libs")),
    ("zenoh", ("zenoh",)),
    ("mujoco", ("mujoco",)),
    ("foxglove", ("foxglove",)),
    ("python", ("libpython", "/lib-dynload/", "/bin/python")),
)


def library_of(path: str) -> str:
    """The group of :data:`LIBRARIES` a mapping of ``path`` counts to: ``anonymous heap`` for
    memory no file backs (the heaps, the stacks, and what numba's LLVM compiled or loaded),
    ``other .so`` for any other file."""
    if not path or (path.startswith("[") and path != "[vdso]"):
        return "anonymous heap"
    for group, parts in LIBRARIES:
        if any(part in path for part in parts):
            return group
    return "other .so"


def rss_split(pid: int) -> dict[str, float]:
    """MB resident of each group of :func:`library_of`, from ``/proc/PID/smaps``, largest first."""
    split: dict[str, float] = {}
    group = "anonymous heap"
    for line in Path(f"/proc/{pid}/smaps").read_text(encoding="utf-8").splitlines():
        head = line.split(maxsplit=5)
        if len(head) >= 5 and "-" in head[0] and not head[0].endswith(":"):
            group = library_of(head[5].strip() if len(head) == 6 else "")
        elif head and head[0] == "Rss:":
            split[group] = split.get(group, 0.0) + int(head[1]) / 1024
    return {g: round(mb, 1) for g, mb in sorted(split.items(), key=lambda kv: -kv[1])}


# The daemon's start in the order percept run goes through it, in a fresh interpreter that stops
# after each stage until the parent has read its memory (a line on stdin).
STAGES = (
    ("interpreter", ""),
    ("numpy, OpenCV", "import numpy, cv2"),
    ("Zenoh", "import zenoh"),
    ("numba (LLVM initialised)", "import percept.perception.compiled"),
    (
        "percept run's modules",
        "import percept.runtime.commands.robot.run, percept.runtime.daemon.daemon, "
        "percept.runtime.daemon.devices, percept.runtime.daemon.pipeline",
    ),
    (
        "numba's first kernel",
        "from percept.perception.compiled.boxes_kernels import pixel_span\n"
        "pixel_span(0.5, 0.5, 3.0, 2.0, 10, 10)",
    ),
    ("every kernel (warm-up)", "from percept.perception.warm import warm_up\nwarm_up()"),
)


def memory_stages() -> list[dict]:
    """Resident memory (MB, and :func:`rss_split`) and the number of modules imported of a
    fresh interpreter after each of :data:`STAGES`, with the user's kernel cache: where the
    daemon's memory comes from before its first frame."""
    code = "import sys\n" + "".join(
        f"{stmt}\nprint({name!r}, len(sys.modules), sep='\\t', flush=True)\nsys.stdin.readline()\n"
        for name, stmt in STAGES
    )
    child = subprocess.Popen(
        [sys.executable, "-c", code],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    assert child.stdin is not None and child.stdout is not None
    rows = []
    try:
        for name, _stmt in STAGES:
            said, _, modules = child.stdout.readline().strip().partition("\t")
            if said != name:
                raise RuntimeError(f"memory stages: expected {name!r}, the child said {said!r}")
            memory = memory_mb(child.pid)
            rows.append(
                {
                    "stage": name,
                    "modules": int(modules),
                    "rss_mb": round(memory["VmRSS"], 1),
                    "rss_anon_mb": round(memory["RssAnon"], 1),
                    "rss_split_mb": rss_split(child.pid),
                }
            )
            child.stdin.write("\n")
            child.stdin.flush()
    finally:
        child.kill()
        child.wait()
    return rows


def by_thread(statuses: list[dict]) -> dict[str, float]:
    """Mean % of one core of each thread over ``statuses`` (their ``cpu_threads``), largest
    first, those under 0.05 % left out."""
    from percept.runtime.daemon.status.health import mean_shares

    mean = mean_shares([s.get("cpu_threads", {}) for s in statuses])
    return {n: round(100 * v, 1) for n, v in mean.items() if v >= 0.0005}


def measure(
    name: str,
    run: Run,
    seconds: float,
    warmup: float,
    log_dir: Path,
    cache: Path,
    lead: float,
    skew: float = 0.0,
    calibrate: bool = False,
) -> dict:
    """One run of the daemon: ``seconds`` measured ``warmup`` seconds after its background is
    there. A recorded run's background is calibrated once on the head's sweep (``calibrate``:
    only that, by a first run) and loaded from the recording's folder."""
    fps = 30.0
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        recording = None
        # calibration + start-up + warm-up + measurement, with room to spare
        length = warmup + seconds + 15
        if run.mode == "folder" and run.head == "pan":
            recording = record_run(run, cache / f"{name}-{length:g}s", length, fps)
        every = run.every
        calibration = None if recording is None else recording.calibration_frames
        experiment, endpoint = experiment_for(tmp, every, calibration)
        cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
        cmd += ["--name", "a"]
        if recording is not None:
            background = recording.frames.parent / "background.npz"
            if not calibrate and not background.is_file():
                print(f"calibrating {name}'s background once into {background}", file=sys.stderr)
                measure(name, run, seconds, warmup, log_dir, cache, lead, calibrate=True)
            cmd += ["--background", str(background)]
        emulator = None
        epoch = None
        if run.mode == "sim":
            cmd += ["--robot", str(run.profile), "--sim", scene_file(run, tmp)]
        else:
            port = tmp / "servos"
            if recording is None:
                frames = cache / f"{name}-{length:g}s"
                angles = render_frames(run.scene, frames, length, fps)
                profile = folder_profile(run.profile, frames, port, tmp)
                emulator = start_emulator(profile, port, angles)
            else:
                # The frames and the joints from one epoch: image i is served at epoch + i/fps
                # and the servos say the recording's angles at that time (then in step however
                # late the daemon's threads run). The lead lets the daemon start first.
                epoch = time.time() + lead
                profile = folder_profile(run.profile, recording.frames, port, tmp, epoch)
                play = (recording.joints, epoch + skew)
                emulator = start_emulator(profile, port, {}, play)
            cmd += ["--robot", str(profile)]
        log_path = log_dir / f"{name}{'-calibrate' if calibrate else ''}.log"
        env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
        with log_path.open("wb") as log_file:
            # stderr to a file, not a pipe nobody reads: a full pipe would stall the daemon
            daemon = subprocess.Popen(cmd, cwd=ROOT, env=env, stderr=log_file)
        watcher = None
        try:
            watcher = Watcher(endpoint)
            ready = ("calibrated", "loaded")
            limit = 900 if calibrate else 90
            if not watcher.wait(lambda s: s.get("background", "").startswith(ready), limit):
                last = watcher.statuses[-1].get("background") if watcher.statuses else None
                raise RuntimeError(
                    f"{name}: no calibrated daemon after {limit} s ({len(watcher.statuses)} "
                    f"statuses, the last background {last!r}); see {log_path}"
                )
            if calibrate:  # saved right after the status said so: wait for the log's word
                while b"background saved" not in log_path.read_bytes():
                    time.sleep(0.2)
                return {}
            if epoch is not None and watcher.first_status_wall > epoch:
                print(
                    f"  {name}: the daemon was up {watcher.first_status_wall - epoch:.1f} s after "
                    f"the recording's first frame: raise --lead",
                    file=sys.stderr,
                )
            if epoch is not None and recording is not None:  # after the sweep, as calibrated
                sweep = recording.calibration_frames / fps
                time.sleep(max(0.0, epoch + sweep - time.time()))
            time.sleep(warmup)
            watcher.measuring = True
            cpu0, t0, wall0 = cpu_seconds(daemon.pid), time.monotonic(), time.time()
            time.sleep(seconds)
            cpu = (cpu_seconds(daemon.pid) - cpu0) / (time.monotonic() - t0)
            watcher.measuring = False
            memory = memory_mb(daemon.pid)
            split = rss_split(daemon.pid)
            status = watcher.statuses[-1]
        finally:
            if watcher is not None:
                watcher.close()
            for proc in (daemon, emulator):
                if proc is not None and proc.poll() is None:
                    proc.send_signal(signal.SIGTERM)
                    try:
                        proc.wait(10)
                    except subprocess.TimeoutExpired:
                        proc.kill()
    ms = sorted(1000 * v for v in watcher.latencies)
    if not ms:
        raise RuntimeError(f"{name}: no world models in the measured window; see {log_path}")
    threads = by_thread(watcher.measured)
    row = {
        "run": name,
        "mode": run.mode,
        "size": "640x480" if run.profile == MYON else "320x200",
        "markers_every": run.every,
        "head": run.head,
        "worlds": len(ms),
        "cpu_cores": round(cpu, 3),
        "cpu_threads": {n: round(v / 100, 3) for n, v in threads.items()},
        "latency_ms_median": round(statistics.median(ms), 2),
        "latency_ms_p90": round(ms[int(0.9 * (len(ms) - 1))], 2),
        "latency_ms_p99": round(ms[int(0.99 * (len(ms) - 1))], 2),
        "fps": status.get("fps"),
        "ms_per_frame": status.get("ms_per_frame"),
        "anchors_mean": round(statistics.fmean(watcher.anchors), 2),
        "cpu_percent_of_one_core": round(100 * cpu, 1),
        "cpu_percent_by_thread": threads,
        "rss_mb": round(memory["VmRSS"], 1),
        "rss_peak_mb": round(memory["VmHWM"], 1),
        "rss_anon_mb": round(memory["RssAnon"], 1),
        "rss_file_mb": round(memory["RssFile"], 1),
        "rss_split_mb": split,
        "daemon_exit": daemon.returncode,
    }
    if epoch is not None:  # the recording's seconds the measurement saw (the head pans to 36 s)
        row["recording_s"] = [round(wall0 - epoch, 1), round(wall0 - epoch + seconds, 1)]
        row["joints_skew_s"] = skew
    return row


def time_to_first_world(
    robot: list[str], experiment: Path, endpoint: str, env: dict, log: Path
) -> tuple[float, float]:
    """Seconds from starting ``percept run`` (robot a with the options ``robot``) to its first
    world model (900 s at most: a cold start on a loaded machine), and the CPU seconds the
    daemon had used by then (the wall time stretches with the machine's load, the CPU time
    much less)."""
    cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
    cmd += ["--name", "a", *robot, "--background", env["PERCEPT_BENCH_BACKGROUND"]]
    watcher = None
    with log.open("wb") as log_file:
        t0 = time.monotonic()
        daemon = subprocess.Popen(cmd, cwd=ROOT, env=env, stderr=log_file)
    try:
        import zenoh

        deadline = t0 + 900
        while watcher is None:  # a cold start compiles before the daemon listens
            try:
                watcher = Watcher(endpoint)
            except zenoh.ZError:
                if time.monotonic() > deadline:
                    raise
        while watcher.first_world is None and time.monotonic() < deadline:
            time.sleep(0.01)
        if watcher.first_world is None:
            raise RuntimeError(f"no world model 900 s after the start; see {log}")
        return watcher.first_world - t0, cpu_seconds(daemon.pid)
    finally:
        if watcher is not None:
            watcher.close()
        daemon.send_signal(signal.SIGTERM)
        try:
            daemon.wait(10)
        except subprocess.TimeoutExpired:
            daemon.kill()


def startup(
    name: str, run: Run, log_dir: Path, cache: Path, length: float, cold_too: bool = True
) -> dict:
    """Start-up of ``run`` with a cold and a warm cache of compiled kernels (``cold_too``
    false: only warm, the user's cache): ``--sim``, or the robot as onboard (``folder``: the
    image folder, and the servos emulated by a process that runs already, as a servo bus is
    powered before the daemon starts)."""
    # pip byte-compiles an installed package; a checkout run with PYTHONDONTWRITEBYTECODE (as
    # some containers set it) would compile its sources at every start (0.25 s of CPU here).
    for package in ("config", "drivers", "kinematics", "perception", "runtime"):
        compileall.compile_dir(ROOT / package, quiet=2)
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        experiment, endpoint = experiment_for(tmp, run.every)
        env = dict(
            os.environ,
            MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"),
            PERCEPT_BENCH_BACKGROUND=str(tmp / "background.npz"),
        )
        emulator = None
        robot = ["--robot", str(run.profile), "--sim", run.scene]
        if run.mode == "folder":
            frames = cache / f"{name}-{length:g}s"  # as measure() renders them
            angles = render_frames(run.scene, frames, length, 30.0)
            port = tmp / "servos"
            profile = folder_profile(run.profile, frames, port, tmp)
            emulator = start_emulator(profile, port, angles)
            robot = ["--robot", str(profile)]
        try:
            # The first run calibrates and saves the background (with the user's cache of
            # compiled kernels: warm after any earlier run, and not the one timed below).
            log = log_dir / f"{name}-prepare.log"
            time_to_first_world(robot, experiment, endpoint, dict(env), log)
            cold = (math.nan, math.nan)
            if cold_too:
                env["NUMBA_CACHE_DIR"] = str(tmp / "numba")
                log = log_dir / f"{name}-cold.log"
                cold = time_to_first_world(robot, experiment, endpoint, env, log)
                # The cold run is stopped at its first world model, before its warm-up thread
                # has compiled the kernels of later frames (the colour split's, the motion's,
                # the marker search's): the warm-up then completes the cache, as any run longer
                # than its first seconds (or CI's warm-up) does.
                subprocess.run(
                    [sys.executable, "-m", "percept.perception.warm"], cwd=ROOT, env=env,
                    check=True, capture_output=True,
                )  # fmt: skip
            log = log_dir / f"{name}-warm.log"
            warm = time_to_first_world(robot, experiment, endpoint, env, log)
        finally:
            if emulator is not None:
                emulator.send_signal(signal.SIGTERM)
                emulator.wait(10)
    return {
        "run": name,
        "cold_s": round(cold[0], 2),
        "cold_cpu_s": round(cold[1], 2),
        "warm_s": round(warm[0], 2),
        "warm_cpu_s": round(warm[1], 2),
    }


def time_detector(run: Run, seconds: float) -> dict:
    """The marker search's ms per image (median, p90) and the whole-image AprilTag search's, on
    ``seconds`` of ``run``'s frames at 30 fps; markers found and their corners' largest gap."""
    import cv2
    import numpy as np

    from percept.perception.landmarks.detection.detector import MarkerDetector, load_dictionary
    from percept.runtime.settings.experiment import load_experiment

    cv2.setNumThreads(1)
    settings = load_experiment(EXPERIMENT).landmarks
    detector = MarkerDetector.from_settings(settings)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
    whole = cv2.aruco.ArucoDetector(load_dictionary(settings.dictionary), params)
    with tempfile.TemporaryDirectory() as tmp_name:
        render_frames(run.scene, Path(tmp_name) / "frames", seconds, 30.0)
        paths = sorted((Path(tmp_name) / "frames").glob("*.jpg"))
        images = [cv2.cvtColor(cv2.imread(str(f)), cv2.COLOR_BGR2GRAY) for f in paths]
    ms: dict[str, list[float]] = {"percept": [], "whole": []}
    found = {"percept": 0, "whole": 0}
    gaps = [0.0]
    for image in images:
        t0 = time.perf_counter()
        markers = {m.id: m.corners for m in detector.detect(image)}
        t1 = time.perf_counter()
        corners, ids, _rejected = whole.detectMarkers(image)
        t2 = time.perf_counter()
        ms["percept"].append(1000 * (t1 - t0))
        ms["whole"].append(1000 * (t2 - t1))
        ids = [] if ids is None else ids.ravel().tolist()
        found["percept"] += len(markers)
        found["whole"] += len(ids)
        for i, c in zip(ids, corners, strict=True):
            if i in markers:  # the detector shifts AprilTag's corners by half a pixel
                gaps.append(float(np.abs(markers[i] - (c.reshape(4, 2) - 0.5)).max()))
    row = {"size": f"{images[0].shape[1]}x{images[0].shape[0]}", "images": len(images)}
    for name, values in ms.items():
        row[f"{name}_ms_median"] = round(float(np.median(values)), 2)
        row[f"{name}_ms_p90"] = round(float(np.percentile(values, 90)), 2)
        row[f"{name}_markers"] = found[name]
    row["largest_corner_gap_px"] = round(max(gaps), 4)
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=15.0, help="measured window per run")
    p.add_argument("--warmup", type=float, default=6.0, help="seconds after calibration")
    p.add_argument(
        "--runs",
        default="folder-640,folder-640-every1,folder-640-every6,folder-320,sim-640,sim-320",
        help=f"comma-separated, of: {', '.join(RUNS)}",
    )
    p.add_argument("--logs", type=Path, default=Path("out/bench_daemon"), help="daemon logs")
    p.add_argument(
        "--frames",
        type=Path,
        default=Path(tempfile.gettempdir()) / "percept-bench-daemon",
        help="where the folder runs' rendered frames and recordings are kept for later runs",
    )
    p.add_argument(
        "--lead",
        type=float,
        default=12.0,
        help="folder-640-pan: seconds from the start to the recording's first frame",
    )
    p.add_argument(
        "--skew",
        type=float,
        default=0.0,
        help="folder-640-pan: the joints this many seconds behind the frames (a check of the "
        "instrument: frames and joints out of step show as false anchors)",
    )
    p.add_argument("--json", action="store_true", help="only one JSON line per run")
    p.add_argument(
        "--warm-only", action="store_true", help="--startup: only warm, with the user's cache"
    )
    p.add_argument("--detector", action="store_true", help="time only the marker search, no daemon")
    p.add_argument(
        "--startup", action="store_true", help="time to the first world model, cold and warm"
    )
    p.add_argument(
        "--memory-stages",
        action="store_true",
        help="resident memory after each stage of the daemon's start, in a fresh interpreter",
    )
    args = p.parse_args()
    if args.memory_stages:
        rows = memory_stages()
        if args.json:
            for r in rows:
                print(json.dumps(r), flush=True)
            return
        print(f"resident memory by stage of the start, load average {os.getloadavg()[0]:.1f}")
        print(f"{'stage':26} {'modules':>7} {'RSS MB':>7} {'anon':>6}  by library")
        for r in rows:
            split = ", ".join(f"{n} {v:.0f}" for n, v in r["rss_split_mb"].items() if v >= 0.5)
            print(
                f"{r['stage']:26} {r['modules']:>7} {r['rss_mb']:>7.1f} {r['rss_anon_mb']:>6.1f}"
                f"  {split}"
            )
        return
    if args.startup:
        args.logs.mkdir(parents=True, exist_ok=True)
        print(f"start-up of percept run, load average {os.getloadavg()[0]:.1f}")
        print(f"{'run':10} {'cold s':>7} {'(CPU s)':>8} {'warm s':>7} {'(CPU s)':>8}")
        for name in [n.strip() for n in args.runs.split(",")]:
            if RUNS[name].head != "as in the scene":
                p.error(f"--startup: {name} has a moving head; time sim-640 or folder-640")
            length = args.warmup + args.seconds + 15
            r = startup(name, RUNS[name], args.logs, args.frames, length, not args.warm_only)
            print(
                f"{name:10} {r['cold_s']:>7.2f} {r['cold_cpu_s']:>8.2f} {r['warm_s']:>7.2f} "
                f"{r['warm_cpu_s']:>8.2f}",
                flush=True,
            )
        return
    if args.detector:
        print(f"marker search, one thread, load average {os.getloadavg()[0]:.1f}")
        print(
            f"{'size':8} {'images':>6} {'percept ms med/p90':>18} {'whole-image ms med/p90':>22} "
            f"{'markers':>11} {'gap px':>6}"
        )
        for name in ("folder-640", "folder-320"):
            r = time_detector(RUNS[name], args.seconds)
            print(
                f"{r['size']:8} {r['images']:>6} {r['percept_ms_median']:>9.2f} / "
                f"{r['percept_ms_p90']:<6.2f} {r['whole_ms_median']:>13.2f} / "
                f"{r['whole_ms_p90']:<6.2f} {r['percept_markers']:>5}/{r['whole_markers']:<5} "
                f"{r['largest_corner_gap_px']:>6.3f}",
                flush=True,
            )
        return
    args.logs.mkdir(parents=True, exist_ok=True)
    names = [n.strip() for n in args.runs.split(",") if n.strip()]
    unknown = [n for n in names if n not in RUNS]
    if unknown:
        p.error(f"unknown run(s) {', '.join(unknown)}; known: {', '.join(RUNS)}")
    say = print if not args.json else lambda *_a, **_k: None
    say(f"load average before: {os.getloadavg()[0]:.1f}; {args.seconds:g} s per run")
    header = (
        f"{'run':18} {'size':8} {'every':>5} {'lat med':>8} {'lat p99':>8} {'fps':>5} "
        f"{'ms/fr':>6} {'anch':>5} {'CPU %':>6} {'RSS MB':>7} {'peak':>6}"
    )
    say(header)
    for name in names:
        r = measure(name, RUNS[name], args.seconds, args.warmup, args.logs, args.frames, args.lead)
        r["load_average"] = round(os.getloadavg()[0], 2)
        if args.json:
            print(json.dumps(r), flush=True)
            continue
        print(
            f"{name:18} {r['size']:8} {r['markers_every']:>5} {r['latency_ms_median']:>8.2f} "
            f"{r['latency_ms_p99']:>8.2f} {r['fps'] or 0:>5.1f} {r['ms_per_frame'] or 0:>6.2f} "
            f"{r['anchors_mean']:>5.1f} {r['cpu_percent_of_one_core']:>6.1f} "
            f"{r['rss_mb']:>7.1f} {r['rss_peak_mb']:>6.1f}",
            flush=True,
        )
        threads = ", ".join(f"{n} {v:.1f}" for n, v in r["cpu_percent_by_thread"].items())
        print(f"  CPU % by thread: {threads}", flush=True)
        split = ", ".join(f"{n} {v:.0f}" for n, v in r["rss_split_mb"].items())
        print(f"  RSS MB by library: {split}", flush=True)
        print("  " + json.dumps(r), flush=True)
    say(f"load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
