"""How ``percept`` answers the careless and hostile inputs of issue 14 (items 8-12): each case run
as a ``percept`` process, with its exit code, the seconds until it exited, its peak resident
memory and the first line it printed about the problem.

    python bench/bad_inputs.py
"""

from __future__ import annotations

import os
import socket
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENT = ROOT / "config" / "experiments" / "tabletop.toml"
OP3 = ROOT / "config" / "robots" / "robotis-op3.toml"
MARKERS = ROOT.parent / "shared" / "data" / "opencv-aruco-tutorial" / "singlemarkersoriginal.jpg"


def _experiment(tmp: Path, extra: str = "", endpoint: str = "tcp/127.0.0.1:7447") -> Path:
    path = tmp / "exp.toml"
    robot = f'[[robots]]\nname = "a"\nprofile = "{OP3}"\nendpoint = "{endpoint}"\n'
    path.write_text(f'name = "x"\n{extra}\n{robot}', encoding="utf-8")
    return path


def _profile(tmp: Path, lens: str = "", kinematics: str = "") -> Path:
    text = OP3.read_text(encoding="utf-8").replace("[camera.lens]\n", f"[camera.lens]\n{lens}\n", 1)
    path = tmp / "robot.toml"
    path.write_text(
        text.replace("[kinematics]\n", f"[kinematics]\n{kinematics}\n", 1), encoding="utf-8"
    )
    return path


def _png(path: Path, width: int, height: int, rows: int) -> Path:
    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = struct.pack(">I", zlib.crc32(kind + data))
        return struct.pack(">I", len(data)) + kind + data + crc

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    packer = zlib.compressobj(9)  # row by row: this process stays small (its children's peak
    row = b"\0" * (width + 1)  # memory starts from it)
    data = b"".join(packer.compress(row) for _ in range(rows)) + packer.flush()
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data)
    path.write_bytes(png + chunk(b"IEND", b""))
    return path


def cases(tmp: Path) -> list[tuple[str, Callable[[], list[str]]]]:
    run = ["run", "--sim", "tabletop-basic", "--experiment"]

    def background() -> list[str]:
        (tmp / "bg.npz").write_bytes(os.urandom(5000))
        return [*run, str(EXPERIMENT), "--background", str(tmp / "bg.npz")]

    def intrinsics() -> list[str]:
        (tmp / "cam.yml").write_bytes(os.urandom(3000))
        return ["config", "--robot", str(_profile(tmp, lens='intrinsics = "cam.yml"'))]

    def urdf() -> list[str]:
        (tmp / "robot.urdf").mkdir(exist_ok=True)
        return ["config", "--robot", str(_profile(tmp, kinematics='urdf = "robot.urdf"'))]

    def deep() -> list[str]:
        (tmp / "deep.toml").write_text("a = " + "[" * 100_000 + "]" * 100_000, encoding="utf-8")
        return ["config", "--experiment", str(tmp / "deep.toml")]

    def markers() -> list[str]:
        huge = _png(tmp / "huge.png", 60000, 60000, 0)
        return ["markers", str(huge), str(MARKERS), "--dict", "DICT_6X6_250"]

    def bomb() -> list[str]:
        gt, masks = tmp / "gt", tmp / "masks"
        gt.mkdir(exist_ok=True)
        masks.mkdir(exist_ok=True)
        _png(gt / "gt000001.png", 30000, 30000, 30000)  # about 1 MB, 900 MB decoded
        _png(masks / "000001.png", 30000, 30000, 0)
        return ["eval", "foreground", "--gt", str(gt), "--masks", str(masks)]

    return [
        (
            "answer_timeout = 1e308",
            lambda: [
                "config",
                "--experiment",
                str(_experiment(tmp, "[peers]\nanswer_timeout = 1e308")),
            ],
        ),
        (
            "calibration_frames = 100000",
            lambda: [
                *run,
                str(_experiment(tmp, "[perception.background]\ncalibration_frames = 100000")),
            ],
        ),
        ("deeply nested TOML", deep),
        ("URDF path is a folder", urdf),
        (
            'prefix = "percept/**"',
            lambda: ["config", "--experiment", str(_experiment(tmp, 'prefix = "percept/**"'))],
        ),
        (
            'prefix = "a?#"',
            lambda: ["config", "--experiment", str(_experiment(tmp, 'prefix = "a?#"'))],
        ),
        (
            "endpoint tcp/127.0.0.1:99999",
            lambda: [
                "config",
                "--experiment",
                str(_experiment(tmp, endpoint="tcp/127.0.0.1:99999")),
            ],
        ),
        (
            "endpoint nonsense",
            lambda: ["config", "--experiment", str(_experiment(tmp, endpoint="nonsense"))],
        ),
        ("intrinsics of random bytes", intrinsics),
        ("--background of random bytes", background),
        ("--record a folder", lambda: [*run, str(EXPERIMENT), "--record", str(tmp)]),
        (
            "--record in a missing folder",
            lambda: [*run, str(EXPERIMENT), "--record", str(tmp / "no" / "a.mcap")],
        ),
        ("port in use", lambda: [*run, str(EXPERIMENT)]),
        ("markers: 60000x60000 PNG, then a good image", markers),
        ("eval foreground: 1 MB decompression bomb", bomb),
    ]


def measure(argv: list[str]) -> tuple[int, float, float, str]:
    """(exit code, seconds, peak resident MB, first problem line) of ``percept argv``."""
    cmd = [sys.executable, "-m", "percept.runtime.cli", *argv]
    with tempfile.TemporaryFile() as output:
        began = time.monotonic()
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=output, stderr=output)
        _, status, usage = os.wait4(proc.pid, 0)  # reaped here: its own peak memory
        seconds = time.monotonic() - began
        proc.returncode = os.waitstatus_to_exitcode(status)
        output.seek(0)
        lines = output.read().decode(errors="replace").splitlines()
    said = next((ln for ln in lines if "percept: " in ln or "declares" in ln), "")
    return proc.returncode, seconds, usage.ru_maxrss / 1024, said[:150]


def main() -> int:
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        print(f"{'case':46} exit  seconds  peak MB  says")
        for name, make in cases(tmp):
            argv = make()
            if name == "port in use":
                holder = socket.socket()
                holder.bind(("127.0.0.1", 7447))
                holder.listen()
            try:
                code, seconds, peak, said = measure(argv)
            finally:
                if name == "port in use":
                    holder.close()
            print(f"{name:46} {code:4}  {seconds:7.2f}  {peak:7.0f}  {said}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
