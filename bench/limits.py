"""Goals outside the head's limits over glitched, muted and unplugged cycles (must be 0).

Runs the real Dynamixel driver against the servo emulator for ``--cycles`` read periods (10 ms
each) per protocol, a fault starting in a ``--fault-rate`` share of them: impossible positions
in valid replies, corrupt replies, a mute servo, the port unplugged, the shaft pushed past a
limit, hardware error bits, disengage, the bus stopped and restarted; goals asked for anywhere.
Then it counts, from the emulator's log of every goal position its servos took, the goals
outside each joint's limits (see tests/support/head_limits.py).

    python bench/limits.py [--cycles 10000] [--protocol 2.0 1.0] [--seed 0]
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.support import head_limits  # noqa: E402


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cycles", type=int, default=10_000, help="read periods per protocol")
    p.add_argument("--protocol", type=float, nargs="+", default=[2.0, 1.0], choices=[2.0, 1.0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--fault-rate", type=float, default=0.03, help="share of cycles starting one")
    args = p.parse_args()
    logging.basicConfig(level=logging.ERROR)  # the driver warns at every fault: thousands
    total = 0
    for protocol in args.protocol:
        outcome = head_limits.run(
            args.cycles,
            protocol,
            args.seed,
            args.fault_rate,
            lambda done: print(".", end="", flush=True) if done % 1000 == 0 else None,
        )
        outside = sum(len(v) for v in outcome.outside.values())
        total += outside
        faults = ", ".join(f"{k} {n}" for k, n in sorted(outcome.injected.items()))
        print(
            f"\nprotocol {protocol}, profile {head_limits.PROFILES[protocol]}: "
            f"{outcome.cycles} cycles in {outcome.seconds:.0f} s\n"
            f"  faults started: {faults}\n"
            f"  gaze stopped on a fault {outcome.stops} times; readings not used: "
            f"{outcome.bad_readings}\n"
            f"  goals taken: "
            + ", ".join(f"{n} {c}" for n, c in outcome.goals.items())
            + f"\n  goals outside the limits: {outside}"
            + (f" {outcome.outside}" if outside else "")
        )
    print(f"\nout-of-limit goals, all protocols: {total}")
    return 0 if total == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
