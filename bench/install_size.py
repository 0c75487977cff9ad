"""The size on disk of a virtual environment, by installed distribution.

Every file of the venv is charged once: to the distribution whose RECORD lists it, a compiled
``__pycache__/*.pyc`` to the distribution of its source, a folder to the distribution of what it
holds; the rest (the interpreter links, pip's own cache files) is one row of its own. Sizes are
blocks on disk, as ``du`` counts them, in MB of 2^20 bytes.

    python3 -m venv /tmp/onboard && /tmp/onboard/bin/pip install .
    python bench/install_size.py /tmp/onboard
    python bench/install_size.py /tmp/onboard --json
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import sys
from collections import Counter
from pathlib import Path

NOBODY = "(not a distribution)"


def site_packages(venv: Path) -> Path:
    """The venv's site-packages folder (lib/pythonX.Y/site-packages)."""
    found = sorted(venv.glob("lib/python3*/site-packages"))
    if len(found) != 1:
        raise SystemExit(f"{venv}: expected one lib/python3*/site-packages, found {len(found)}")
    return found[0]


def owners(site: Path) -> dict[str, str]:
    """Distribution name by the normalised path of every file a RECORD lists."""
    out: dict[str, str] = {}
    for dist in importlib.metadata.distributions(path=[str(site)]):
        for f in dist.files or []:
            out[os.path.normpath(site / f)] = dist.metadata["Name"]
    return out


def _owner(path: str, owned: dict[str, str]) -> str | None:
    """The distribution of a file: its RECORD's, or for ``__pycache__/x.cpython-3y.pyc`` x.py's."""
    if path in owned:
        return owned[path]
    folder, name = os.path.split(path)
    if os.path.basename(folder) == "__pycache__" and name.endswith(".pyc"):
        source = os.path.join(os.path.dirname(folder), name.split(".")[0] + ".py")
        return owned.get(source)
    return None


def sizes(venv: Path) -> dict[str, float]:
    """MB by distribution name, and :data:`NOBODY` for what no distribution owns."""
    owned = owners(site_packages(venv))
    blocks: Counter[str] = Counter()
    folder_owner: dict[str, str | None] = {}
    for root, dirs, files in os.walk(venv, topdown=False):
        found: str | None = None
        for name in files:
            path = os.path.join(root, name)
            who = _owner(path, owned)
            blocks[who or NOBODY] += os.lstat(path).st_blocks
            found = found or who
        for name in dirs:
            found = found or folder_owner.get(os.path.join(root, name))
        folder_owner[root] = found
        blocks[found or NOBODY] += os.lstat(root).st_blocks
    return {name: n * 512 / 2**20 for name, n in blocks.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("venv", type=Path, help="the virtual environment's folder")
    parser.add_argument("--json", action="store_true", help="one JSON object, MB by name")
    args = parser.parse_args(argv)
    by_name = sizes(args.venv)
    total = sum(by_name.values())
    if args.json:
        print(json.dumps({k: round(v, 1) for k, v in by_name.items()} | {"total": round(total, 1)}))
        return 0
    for name, mb in sorted(by_name.items(), key=lambda kv: -kv[1]):
        print(f"{name:32s} {mb:7.1f}")
    print(f"{'total':32s} {total:7.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
