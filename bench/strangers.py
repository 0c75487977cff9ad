"""Memory, frame rate, games and log volume of the onboard daemon under the floods a stranger on
the network can send.

Runs ``percept run --sim tabletop-basic`` as robot a
(:class:`tests.support.fault_rig.ProcessRig`, the shipped timings), waits ``--settle`` seconds,
then a Zenoh client (``python -m tests.support.fault_peer send ENDPOINT KIND COUNT RATE``) floods
it for ``--seconds`` with each ``--flood`` in turn (a fresh daemon each):

- ``strangers``: pointing requests and ``success`` verdicts from made-up robots ``c0``..``c9``;
- ``names``: liveliness tokens of made-up names, each a new one;
- ``long-names``: liveliness tokens of 300-character names (which no robot can have);
- ``words``: a forged robot b teaching robot a a new 64-letter word per guessing game;
- ``huge``: 50 MB payloads on every topic robot a listens to.

Prints, per flood, resident memory from the status's ``rss_mb`` (at the flood's start and end,
its growth and its least-squares slope in MB/s over the flood and over the quiet ``--settle``
seconds before it), the frame rate the statuses gave during the flood (least and median), the
games and word forms the status counts, the rejected messages, and the daemon's log during the
flood in lines and in MB per hour.

    python bench/strangers.py [--flood names words huge] [--seconds 600] [--rate R]
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

#: Messages (tokens, games, payloads) per second of each flood by default: the strangers under
#: the flood alarm in all, 20,000 names in ten minutes, the issue's 40 games a second, a 50 MB
#: payload a second.
RATES = {"strangers": 570.0, "names": 35.0, "long-names": 35.0, "words": 40.0, "huge": 1.0}


def _slope(statuses: list[tuple[float, dict]]) -> float:
    """Least-squares growth of ``rss_mb`` in MB/s."""
    t = np.array([t for t, _ in statuses])
    return float(np.polyfit(t - t[0], [s["rss_mb"] for _, s in statuses], 1)[0])


def flood(kind: str, seconds: float, rate: float, settle: float) -> bool:
    """One flood against a fresh daemon; prints its figures; whether the daemon stayed up."""
    with tempfile.TemporaryDirectory() as tmp:
        rig = ProcessRig(Path(tmp), short=False).start()
        try:
            # The first frames of a fresh install wait for numba's kernels: flood a daemon at work.
            working = rig.watch.first_status(time.monotonic(), lambda s: s["fps"] > 0, 600.0)
            if working is None:
                raise RuntimeError(f"robot a made no frame in 600 s: {rig.watch.statuses[-1]}")
            quiet = time.monotonic()
            time.sleep(settle)
            count = max(1, int(seconds * rate))
            sender = Sender(endpoint(rig.experiment, "a"), kind, count, rate)
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
    fps = [s["fps"] for _, s in during]
    slope = _slope(during)
    before = _slope([(t, s) for t, s in statuses if quiet <= t < began])
    last = during[-1][1]
    log_mb = sum(len(line) + 1 for line in lines) / 1e6
    hours = (ended - began) / 3600
    print(f"== {kind}: {count} at {rate:g}/s for {ended - began:.1f} s to robot a", end="")
    print(f" (load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the end)")
    print(
        f"resident memory: {rss[0]:.1f} MB at the start, {rss[-1]:.1f} MB at the end "
        f"(growth {rss[-1] - rss[0]:+.1f} MB, most {max(rss):.1f} MB)"
    )
    print(f"slope over the flood: {slope:+.4f} MB/s ({len(during)} statuses)")
    print(f"slope over the quiet {settle:g} s before it: {before:+.4f} MB/s")
    print(f"frame rate during the flood: least {min(fps):.1f}, median {np.median(fps):.1f} fps")
    games = last["games"]
    print(f"status games: {games}")
    print(f"rejected messages: {last['rejected_messages']}, inbox dropped {last['inbox_dropped']}")
    print(f"faults at the end of the flood: {last['faults']}")
    print(f"log during the flood: {len(lines)} lines, {log_mb / hours:.2f} MB/h")
    print(f"daemon up throughout: {'yes' if alive else 'NO'}", flush=True)
    return alive


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--flood", nargs="+", choices=sorted(RATES), default=["strangers"])
    p.add_argument("--seconds", type=float, default=90.0, help="how long each flood lasts")
    p.add_argument("--rate", type=float, help="per second (default: the flood's, see RATES)")
    p.add_argument("--settle", type=float, default=30.0, help="quiet seconds before the flood")
    args = p.parse_args()
    up = [flood(k, args.seconds, args.rate or RATES[k], args.settle) for k in args.flood]
    return 0 if all(up) else 1


if __name__ == "__main__":
    sys.exit(main())
