"""Soak test of the onboard daemon: does anything grow when it runs for a long time?

Runs ``percept run --sim tabletop-busy`` as robot a (the real CLI in its own process, the scene
looped with ``[sim] loop = true`` so the experimenter keeps adding, moving, hiding and removing
objects) for ``--minutes`` and every ``--every`` seconds prints the daemon's resident memory,
thread count and open file descriptors (from /proc), and the anchors in its world models on
Zenoh (now, mean and most over the interval, and how many new anchor ids appeared). Ends with
a verdict: memory, threads and open files flat after the warm-up, and no anchor leak (the most
anchors in any world model at most the scene's object count, and no upward trend).

    python bench/soak.py [--minutes 20 --every 30 --scene tabletop-busy]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.support.daemon import endpoint, experiment_copy  # noqa: E402

MEMORY_SLACK_MB = 8.0  # growth after the warm-up still called flat (allocator noise)


@dataclass
class Window:
    """The world models and status seen since the last sample."""

    anchors: list[int] = field(default_factory=list)
    ids: set[object] = field(default_factory=set)
    status: dict | None = None


class Watcher:
    """A Zenoh client on the daemon's endpoint collecting anchors per world model."""

    def __init__(self, ep: str) -> None:
        import zenoh

        from percept.runtime.net.zenoh_config import client_config

        self._lock = threading.Lock()
        self._window = Window()
        self.seen_ids: set[object] = set()
        self.worlds = 0
        self.session = zenoh.open(client_config([ep], connect_timeout=None))
        self._subs = [
            self.session.declare_subscriber("percept/a/world", self._on_world),
            self.session.declare_subscriber("percept/a/status", self._on_status),
        ]

    def _on_world(self, sample) -> None:
        world = json.loads(sample.payload.to_bytes())
        with self._lock:
            self.worlds += 1
            self._window.anchors.append(len(world["objects"]))
            self._window.ids.update(o["id"] for o in world["objects"])

    def _on_status(self, sample) -> None:
        with self._lock:
            self._window.status = json.loads(sample.payload.to_bytes())

    def take(self) -> Window:
        with self._lock:
            window, self._window = self._window, Window()
        return window

    def close(self) -> None:
        self.session.close()


def proc_sample(pid: int) -> tuple[float, int, int]:
    """(resident MB, threads, open file descriptors) of process ``pid``."""
    fields = {}
    for line in Path(f"/proc/{pid}/status").read_text(encoding="utf-8").splitlines():
        key, _, value = line.partition(":")
        fields[key] = value.strip()
    rss = int(fields["VmRSS"].split()[0]) / 1000.0
    return rss, int(fields["Threads"]), len(os.listdir(f"/proc/{pid}/fd"))


def slope_per_hour(times: list[float], values: list[float]) -> float:
    """Least-squares slope of values over times (seconds), per hour."""
    if len(times) < 2:
        return 0.0
    return statistics.linear_regression(times, values).slope * 3600.0


def scene_objects(name: str) -> int:
    from percept.runtime.settings.scene import find_scene, load_scene

    scene, _ = load_scene(find_scene(name))
    return len(scene.objects)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=20.0, help="how long (default 20)")
    p.add_argument("--every", type=float, default=30.0, help="seconds between samples")
    p.add_argument("--scene", default="tabletop-busy", help="simulated scene (looped)")
    p.add_argument(
        "--warmup", type=float, default=None, help="minutes ignored by the verdict (default 2)"
    )
    args = p.parse_args()
    warmup = 60.0 * (args.warmup if args.warmup is not None else min(2.0, args.minutes / 4))
    bound = scene_objects(args.scene)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        experiment = experiment_copy(tmp)
        text = experiment.read_text(encoding="utf-8").replace("[sim]\n", "[sim]\nloop = true\n", 1)
        experiment.write_text(text, encoding="utf-8")
        log_path = tmp / "daemon.log"
        cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
        cmd += ["--name", "a", "--sim", args.scene]
        env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
        with open(log_path, "wb") as log_file:
            proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stderr=log_file, stdout=log_file)
        watcher = Watcher(endpoint(experiment, "a"))
        print(f"soak: {' '.join(cmd[2:])} (pid {proc.pid}) for {args.minutes:g} min")
        print(f"scene {args.scene}: {bound} objects; warm-up {warmup / 60:g} min\n")
        header = (
            f"{'min':>6} {'rss MB':>7} {'threads':>7} {'fds':>4} {'anchors':>7} {'mean':>5} "
            f"{'max':>4} {'new ids':>7} {'fps':>5}  faults"
        )
        print(header)
        rows: list[tuple[float, float, int, int, int]] = []
        began = time.monotonic()
        end = began + 60.0 * args.minutes
        try:
            while time.monotonic() < end and proc.poll() is None:
                time.sleep(min(args.every, max(0.0, end - time.monotonic())))
                if proc.poll() is not None:
                    break
                elapsed = time.monotonic() - began
                rss, threads, fds = proc_sample(proc.pid)
                window = watcher.take()
                new_ids = window.ids - watcher.seen_ids
                watcher.seen_ids |= window.ids
                most = max(window.anchors, default=0)
                mean = statistics.fmean(window.anchors) if window.anchors else 0.0
                now = window.anchors[-1] if window.anchors else 0
                status = window.status or {}
                faults = "; ".join(status.get("faults", [])) or "-"
                print(
                    f"{elapsed / 60:6.1f} {rss:7.1f} {threads:7d} {fds:4d} {now:7d} {mean:5.1f} "
                    f"{most:4d} {len(new_ids):7d} {status.get('fps', 0):5.1f}  {faults}",
                    flush=True,
                )
                rows.append((elapsed, rss, threads, fds, most))
        finally:
            ended = proc.poll() is not None
            if not ended:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()
            watcher.close()
        log_text = log_path.read_text(encoding="utf-8", errors="replace")
        code = proc.returncode
    return verdict(rows, warmup, bound, ended, code, log_text, watcher.worlds)


def verdict(
    rows: list[tuple[float, float, int, int, int]],
    warmup: float,
    bound: int,
    ended_early: bool,
    code: int | None,
    log_text: str,
    worlds: int,
) -> int:
    """Print the verdict; the exit code (0: everything flat)."""
    late = [r for r in rows if r[0] >= warmup]
    problems = []
    if ended_early:
        problems.append(f"the daemon ended by itself (exit {code})")
    if len(late) < 2:
        problems.append("too few samples after the warm-up for a verdict")
    print()
    print(f"world models received: {worlds}")
    if late:
        t = [r[0] for r in late]
        rss = [r[1] for r in late]
        growth = rss[-1] - rss[0]
        fitted = slope_per_hour(t, rss) * (t[-1] - t[0]) / 3600.0
        threads = {r[2] for r in late}
        fds = [r[3] for r in late]
        most = max(r[4] for r in rows)
        print(
            f"after warm-up: rss {rss[0]:.1f} -> {rss[-1]:.1f} MB (fitted growth {fitted:+.1f} MB, "
            f"{slope_per_hour(t, rss):+.1f} MB/h), threads {sorted(threads)}, open files "
            f"{min(fds)}..{max(fds)}, most anchors in a world model {most} (scene objects {bound})"
        )
        if max(growth, fitted) > MEMORY_SLACK_MB:
            problems.append(f"memory grows ({fitted:+.1f} MB fitted over the run)")
        if len(threads) > 1:
            problems.append(f"thread count changes: {sorted(threads)}")
        if max(fds) - min(fds) > 2:
            problems.append(f"open files change: {min(fds)}..{max(fds)}")
        if most > bound:
            problems.append(f"{most} anchors in one world model, the scene has {bound} objects")
    lines = [ln for ln in log_text.splitlines() if " WARNING " in ln or " ERROR " in ln]
    print(f"daemon log: {len(lines)} warnings and errors")
    # The same message with other numbers counts once: strip the time and the digits.
    kinds = collections.Counter(re.sub(r"[0-9.]+", "#", ln.split(" ", 2)[-1]) for ln in lines)
    for text, count in kinds.most_common(5):
        print(f"  {count:5d} x {text[:150]}")
    print("verdict:", "flat, no anchor leak" if not problems else "; ".join(problems))
    return 0 if not problems else 1


if __name__ == "__main__":
    sys.exit(main())
