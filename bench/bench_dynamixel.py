"""Dynamixel driver speed against the pty emulator: read transactions and the reader thread.

1. One read of present position through ``Link`` (the SDK behind the driver's port seam), as the
   reader makes them: a Protocol 2.0 sync read of all servos, and 1.0 single reads; milliseconds
   per transaction, median and p90.
2. ``DynamixelBus`` at several rates for a few seconds each: reads per second achieved and the
   CPU the whole process (driver and emulator threads) used, in percent of one core.

The emulator runs in the same process, so its CPU is counted too; over a real USB adapter the
transaction time is dominated by the adapter (FTDI latency timer: see README "Hardware notes").

    python bench/bench_dynamixel.py [--reads 2000] [--seconds 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from percept.drivers.dynamixel.bus import DynamixelBus  # noqa: E402
from percept.drivers.dynamixel.emulator import ServoEmulator  # noqa: E402
from percept.drivers.dynamixel.errors import ReadFailed  # noqa: E402
from percept.drivers.dynamixel.link import Link  # noqa: E402
from percept.drivers.dynamixel.settings import BusSettings, JointSettings  # noqa: E402

SERVOS = {
    2.0: [JointSettings("head_pan", 19), JointSettings("head_tilt", 20)],
    1.0: [
        JointSettings("head_pan", 24, model="MX-28"),
        JointSettings("head_tilt", 25, model="MX-28"),
    ],
}


def p90(values: list[float]) -> float:
    return sorted(values)[int(0.9 * (len(values) - 1))]


def transactions(protocol: float, reads: int) -> tuple[list[float], int]:
    """Milliseconds per successful read of all servos, and how many reads failed."""
    joints = SERVOS[protocol]
    with ServoEmulator(joints, protocol) as emu:
        link = Link(emu.port_path, 1_000_000, protocol, 0.05)
        ids = [j.id for j in joints]
        address, size = (132, 4) if protocol == 2.0 else (36, 2)
        took, failed = [], 0
        try:
            for _ in range(reads):
                t0 = time.perf_counter()
                try:
                    if protocol == 2.0:
                        link.sync_read(ids, address, size)
                    else:
                        for servo_id in ids:
                            link.read(servo_id, address, size)
                except ReadFailed:
                    failed += 1  # a loaded machine may starve the emulator thread
                    continue
                took.append((time.perf_counter() - t0) * 1000.0)
        finally:
            link.close()
    return took, failed


def reader(protocol: float, rate: float, seconds: float) -> tuple[float, float]:
    joints = SERVOS[protocol]
    with ServoEmulator(joints, protocol) as emu:
        settings = BusSettings(port=emu.port_path, protocol=protocol, rate=rate)
        with DynamixelBus(settings, joints) as bus:
            time.sleep(1.0)  # connected and settled
            cpu0, wall0 = time.process_time(), time.monotonic()
            time.sleep(seconds)
            cpu = (time.process_time() - cpu0) / (time.monotonic() - wall0) * 100.0
            return bus.status()["reads_per_s"], cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reads", type=int, default=2000)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    print("| protocol | read of 2 servos | ms median | ms p90 | failed |")
    print("|---|---|---|---|---|")
    for protocol in (2.0, 1.0):
        took, failed = transactions(protocol, args.reads)
        how = "sync read" if protocol == 2.0 else "2 single reads"
        median, high = statistics.median(took), p90(took)
        print(f"| {protocol} | {how} | {median:.2f} | {high:.2f} | {failed}/{args.reads} |")
    print()
    print("| protocol | rate asked | reads/s | CPU % of one core |")
    print("|---|---|---|---|")
    for protocol in (2.0, 1.0):
        for rate in (100.0, 250.0):
            achieved, cpu = reader(protocol, rate, args.seconds)
            print(f"| {protocol} | {rate:.0f} | {achieved:.0f} | {cpu:.1f} |")


if __name__ == "__main__":
    main()
