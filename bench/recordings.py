"""What is left of a recording after accidents: a killed daemon restarted on the same
``--record``, a second daemon started on it, and bits flipped or the file cut on disk.

Runs ``percept run --sim tabletop-basic --record a.mcap`` (robot a, shipped timings, free ports)
for ``--seconds``, kills it (SIGKILL) and starts it again on the same file; while that runs, a
second daemon with the same ``--record`` (and port) is started. Then reads the files with the
reader of ``percept replay`` and ``percept stats``
(:func:`percept.runtime.record.reader.read_recording`): world models in the killed file before
and after the restart, and frames read back from copies of the restarted daemon's file with 1, 5 and
50 flipped bits (``--trials`` random placements each) or cut at a quarter, half and three quarters.

    python bench/recordings.py [--seconds 20] [--trials 20]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("MUJOCO_GL", "egl")

from percept.runtime.record.reader import Recording, read_recording  # noqa: E402
from tests.support.fault_rig import SCENE, write_config  # noqa: E402


def daemon(experiment: Path, record: Path, log: Path) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
    cmd += ["--name", "a", "--sim", SCENE, "--record", str(record)]
    return subprocess.Popen(cmd, cwd=ROOT, stderr=log.open("wb"))


def count(path: Path) -> tuple[int, int, Recording]:
    """(frames, world models, what the reader found) in ``path``."""
    recording = Recording(path)
    frames = worlds = 0
    for kind, _ in read_recording(path, recording):
        frames += kind == "frame"
        worlds += kind == "world"
    return frames, worlds, recording


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:12]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=20.0, help="each daemon's run")
    p.add_argument("--trials", type=int, default=20, help="random placements per bit count")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        experiment = write_config(tmp, short=False)
        record = tmp / "a.mcap"

        first = daemon(experiment, record, tmp / "first.log")
        time.sleep(args.seconds)
        first.kill()
        first.wait()
        killed_digest = digest(record)
        _, killed_worlds, _ = count(record)
        print(f"killed daemon: {record.name} holds {killed_worlds} world models")

        restarted = daemon(experiment, record, tmp / "restarted.log")
        time.sleep(args.seconds / 2)
        growing = (tmp / "a.1.mcap").stat().st_size
        second = daemon(experiment, record, tmp / "second.log")
        second_code = second.wait(120)
        time.sleep(2.0)
        grown = (tmp / "a.1.mcap").stat().st_size
        time.sleep(args.seconds / 2)
        restarted.terminate()
        restarted.wait(30)
        _, after_worlds, _ = count(record)
        frames, worlds, _ = count(tmp / "a.1.mcap")
        kept = [
            line
            for line in (tmp / "restarted.log").read_text(encoding="utf-8").splitlines()
            if "kept" in line
        ]
        print(
            f"restart on the same --record: {record.name} unchanged "
            f"{digest(record) == killed_digest}, {after_worlds} world models; "
            f"the restart recorded {worlds} to a.1.mcap; log: {kept[0].split(': ', 1)[-1]}"
        )
        print(
            f"second daemon on the same --record: exit {second_code}; a.1.mcap grew "
            f"{growing} -> {grown} bytes meanwhile; files: "
            + ", ".join(sorted(f.name for f in tmp.glob("*.mcap")))
        )

        intact = (tmp / "a.1.mcap").read_bytes()
        damaged = tmp / "damaged.mcap"
        rng = random.Random(0)
        print(f"\n{len(intact) / 1e6:.1f} MB, {frames} frames intact")
        print("| damage | frames read: median / fewest | chunks skipped: median |")
        print("|---|---|---|")
        for bits in (1, 5, 50):
            read, skipped = [], []
            for _ in range(args.trials):
                data = bytearray(intact)
                for _ in range(bits):
                    data[rng.randrange(8, len(data))] ^= 1 << rng.randrange(8)
                damaged.write_bytes(data)
                got, _, recording = count(damaged)
                read.append(got)
                skipped.append(recording.damage.chunks)
            print(
                f"| {bits} flipped bits ({args.trials} placements) | "
                f"{statistics.median(read):.0f} / {min(read)} | {statistics.median(skipped):.0f} |"
            )
        for quarter in (1, 2, 3):
            damaged.write_bytes(intact[: len(intact) * quarter // 4])
            got, _, recording = count(damaged)
            print(f"| cut at {quarter}/4 | {got} | (truncated {recording.truncated}) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
