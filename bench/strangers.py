"""Memory, games and log volume of the onboard daemon while made-up robots play games with it.

Runs ``percept run --sim tabletop-basic`` as robot a
(:class:`tests.support.fault_rig.ProcessRig`, the shipped timings), waits ``--settle`` seconds,
then a Zenoh client (``python -m tests.support.fault_peer send ENDPOINT strangers COUNT RATE``)
sends pointing requests and ``success`` verdicts from ``c0``..``c9`` (each sender under the
flood rate) to robot a for ``--seconds``. Prints resident
memory from the status's ``rss_mb`` (at the flood's start and end, and its least-squares slope in
MB/s over the flood and over the quiet ``--settle`` seconds before it), the games the status
counts, and the daemon's log during the flood in lines and in MB per hour.

    python bench/strangers.py [--seconds 90] [--rate 570]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("MUJOCO_GL", "egl")

from tests.support.fault_rig import ProcessRig, Sender, endpoint  # noqa: E402


def _slope(statuses: list[tuple[float, dict]]) -> float:
    """Least-squares growth of ``rss_mb`` in MB/s."""
    t = np.array([t for t, _ in statuses])
    return float(np.polyfit(t - t[0], [s["rss_mb"] for _, s in statuses], 1)[0])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=90.0, help="how long the strangers play")
    p.add_argument("--rate", type=float, default=570.0, help="messages per second in all")
    p.add_argument("--settle", type=float, default=30.0, help="quiet seconds before the flood")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rig = ProcessRig(Path(tmp), short=False).start()
        try:
            quiet = time.monotonic()
            time.sleep(args.settle)
            count = int(args.seconds * args.rate)
            sender = Sender(endpoint(rig.experiment, "a"), "strangers", count, args.rate)
            began = sender.start()
            ended = sender.wait()
            time.sleep(2.0)
            alive = rig.alive()
            statuses = list(rig.watch.statuses)
            lines = [line for t, line in rig.logs.lines if began <= t <= ended]
        finally:
            rig.close()
    during = [(t, s) for t, s in statuses if began <= t <= ended]
    rss = [s["rss_mb"] for _, s in during]
    slope = _slope(during)
    before = _slope([(t, s) for t, s in statuses if quiet <= t < began])
    last = statuses[-1][1]
    log_mb = sum(len(line) + 1 for line in lines) / 1e6
    hours = (ended - began) / 3600
    print(f"flood: {count} messages in {ended - began:.1f} s from c0..c9 to robot a")
    print(f"resident memory: {rss[0]:.1f} MB at the start, {rss[-1]:.1f} MB at the end")
    print(f"slope over the flood: {slope:+.4f} MB/s ({len(during)} statuses)")
    print(f"slope over the quiet {args.settle:g} s before it: {before:+.4f} MB/s")
    print(f"status games: {last['games']}")
    print(f"faults at the end of the flood: {during[-1][1]['faults']}")
    print(f"log during the flood: {len(lines)} lines, {log_mb / hours:.2f} MB/h")
    print(f"daemon up throughout: {'yes' if alive else 'NO'}")
    return 0 if alive else 1


if __name__ == "__main__":
    sys.exit(main())
