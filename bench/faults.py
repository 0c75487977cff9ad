"""Fault report and recovery times of the onboard daemon: the scenarios of tests/test_faults.py.

Runs robot a's daemon on the simulated world (in this process; the full disk in a ``percept run``
process) with the shipped timings (``--short``: the tests' shorter ones), injects each fault
``--repeat`` times and prints a table: the time from the fault to the first status naming it
and to the first log line naming it, and from the fault's end to the first status without
faults (median and worst of the repeats), with the status's words for it.

    python bench/faults.py [--repeat 3] [--short] [--only WORDS ...]
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("MUJOCO_GL", "egl")

from tests.support.fault_rig import SCENARIOS, Measurement, ProcessRig, Rig, disk_full  # noqa: E402


def _cell(values: list[float | None]) -> str:
    """``median / worst`` in seconds; a miss counts as the worst."""
    if any(v is None for v in values):
        return "missed"
    got = [v for v in values if v is not None]
    return f"{statistics.median(got):5.2f} / {max(got):5.2f}"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeat", type=int, default=3, help="times each fault is injected")
    p.add_argument("--short", action="store_true", help="the tests' short timings")
    p.add_argument("--hold", type=float, default=1.0, help="seconds a fault lasts once reported")
    p.add_argument(
        "--only",
        nargs="+",
        metavar="WORDS",
        help="only the faults whose names hold one of these words (the full disk: 'disk')",
    )
    args = p.parse_args()
    chosen = [s for s in SCENARIOS if not args.only or any(w in s.name for w in args.only)]
    disk_too = not args.only or any(w in "recording disk full" for w in args.only)
    logging.getLogger().addHandler(logging.NullHandler())  # the daemon's log goes to the rig
    results: dict[str, list[Measurement]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) / "in-process"
        work.mkdir()
        rig = Rig(work, short=args.short).start()
        try:
            for _ in range(args.repeat):
                for s in chosen:
                    m = rig.measure(
                        s.name,
                        s.expect,
                        lambda s=s: s.inject(rig),
                        lambda s=s: s.end(rig),
                        args.hold,
                    )
                    results.setdefault(s.name, []).append(m)
                    print(".", end="", flush=True)
            alive = rig.alive()
        finally:
            rig.close()
        if disk_too:
            disk = Path(tmp) / "process"
            disk.mkdir()
            prig = ProcessRig(disk, short=args.short).start()
            try:
                for _ in range(args.repeat):
                    results.setdefault("recording disk full", []).append(disk_full(prig, args.hold))
                    print(".", end="", flush=True)
                alive = alive and prig.alive()
            finally:
                prig.close()
    print()
    timings = "short (tests)" if args.short else "shipped"
    print(f"timings: {timings}; {args.repeat} times each; seconds, median / worst\n")
    print(f"{'fault':26} {'reported':>13} {'logged':>13} {'recovered':>13}  status says")
    for name, ms in results.items():
        words = next((m.words for m in ms if m.words), "-")
        print(
            f"{name:26} {_cell([m.reported for m in ms]):>13} {_cell([m.logged for m in ms]):>13} "
            f"{_cell([m.recovered for m in ms]):>13}  {words[:90]}"
        )
    print(f"\ndaemon up throughout: {'yes' if alive else 'NO'}")
    return 0 if alive else 1


if __name__ == "__main__":
    sys.exit(main())
