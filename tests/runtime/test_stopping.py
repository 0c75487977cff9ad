"""``percept run`` stopped by SIGINT or SIGTERM at random moments, while other processes load
the machine: robot b and a monitor playing games with it. Each stop must end the process
within two seconds of the signal, with no traceback and the exit code its log explains
(:mod:`percept.runtime.daemon.stopping`): 0 after SIGTERM and 130 after SIGINT once world
models were made, 1 before (the log says why).

The moments fall anywhere from the command line's start to games being played, over a cold
start (an empty compiled-kernel cache: numba compiling) now and then, the background's
calibration and a recording. ``PERCEPT_STOP_RUNS`` sets the number of stops (CI's default
fits in about a minute; 50 for the full check) and ``PERCEPT_STOP_SEED`` their moments.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.support.daemon import ROOT, experiment_copy, start_daemon

RUNS = int(os.environ.get("PERCEPT_STOP_RUNS", "5"))
SEED = int(os.environ.get("PERCEPT_STOP_SEED", str(random.randrange(10**6))))
STOP_WITHIN = 2.0  # seconds from the signal to the end of the process
LATEST = 14.0  # seconds after the first log line: past calibration, into the games
COLD_EVERY = 5  # every fifth stop (the first included) starts with an empty kernel cache
NO_WORLD_MODEL = "no frame processed in"


@pytest.fixture(scope="module")
def others(tmp_path_factory: pytest.TempPathFactory):
    """Robot b and a monitor starting games, for the whole module; the experiment."""
    tmp = tmp_path_factory.mktemp("stops")
    experiment = experiment_copy(tmp)
    peer = start_daemon(experiment, "b")
    cmd = [sys.executable, "-m", "percept.runtime.cli", "monitor", "--experiment", str(experiment)]
    monitor = subprocess.Popen(cmd, cwd=ROOT, stderr=subprocess.DEVNULL)
    try:
        yield experiment
    finally:
        for proc in (monitor, peer):
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def _stop_at(
    experiment: Path, tmp: Path, after: float, sig: int, cold: bool
) -> tuple[int | None, float, str]:
    """Start robot a (recorded), send ``sig`` ``after`` seconds after its first log line (the
    command line loaded: before, Python itself is starting); (exit code, seconds from the
    signal to the end, stderr); the code is None when it had not ended within 30 s."""
    env = {"NUMBA_CACHE_DIR": str(tmp / "kernels")} if cold else {}
    proc = start_daemon(experiment, "a", "--record", str(tmp / "a.mcap"), env=env)
    assert proc.stderr is not None
    lines = [proc.stderr.readline()]
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
    reader.start()
    time.sleep(after)
    sent = time.monotonic()
    proc.send_signal(sig)
    try:
        code: int | None = proc.wait(30)
    except subprocess.TimeoutExpired:
        proc.kill()
        code = None
        proc.wait()
    took = time.monotonic() - sent
    reader.join(10)
    return code, took, b"".join(lines).decode(errors="replace")


def expected_code(sig: int, log: str) -> int:
    """The exit code the stop's log explains."""
    if "stopped before the daemon started" in log:
        return 128 + sig
    if NO_WORLD_MODEL in log:
        return 1
    return 130 if sig == signal.SIGINT else 0


@pytest.mark.timeout(120 + 40 * RUNS)
def test_a_stop_at_any_moment_ends_the_process_within_two_seconds(others, tmp_path) -> None:
    rng = random.Random(SEED)
    failures, seconds = [], []
    for run in range(RUNS):
        after = rng.uniform(0.0, LATEST)
        sig = rng.choice([signal.SIGINT, signal.SIGTERM])
        cold = run % COLD_EVERY == 0
        folder = tmp_path / str(run)
        folder.mkdir()
        code, took, err = _stop_at(others, folder, after, sig, cold)
        seconds.append(took)
        said = f"run {run} (seed {SEED}): {signal.Signals(sig).name} after {after:.1f} s"
        said += f"{' (cold)' if cold else ''}: exit {code} in {took:.2f} s"
        print(said)
        expected = expected_code(sig, err)
        if took > STOP_WITHIN or "Traceback" in err or code != expected:
            last = "\n".join(err.splitlines()[-15:])
            failures.append(f"{said}, expected exit {expected}\n{last}")
    print(f"{RUNS} stops: slowest {max(seconds):.2f} s, median {sorted(seconds)[RUNS // 2]:.2f} s")
    assert not failures, "\n\n".join(failures)
