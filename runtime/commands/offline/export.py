"""``percept export --ros2 REC.mcap OUT``: a recording as a rosbag2 for ROS 2 tools.

OUT is a new rosbag2 directory (``metadata.yaml`` and one MCAP file with ``ros2msg`` schemas)
holding the topics the daemon publishes with ``[ros2]`` enabled (:mod:`percept.runtime.ros2.bag`).
It plays with ``ros2 bag play OUT`` and reads with the ``rosbags`` package.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

NAME = "export"
HELP = "write a recording as a rosbag2 (MCAP) that ROS 2 tools can play"

log = logging.getLogger("percept.export")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--ros2", action="store_true", required=True, help="as a rosbag2 (the one format so far)"
    )
    p.add_argument("recording", metavar="REC.mcap", help="a recording of percept run --record")
    p.add_argument("out", metavar="OUT", help="the rosbag2 directory to write (must not exist)")
    p.add_argument(
        "--namespace", default=None, help="ROS 2 namespace of the topics (default: / + robot name)"
    )


def run(args: argparse.Namespace) -> int:
    from percept.config.extras import require
    from percept.runtime.record.reader import RecordingError

    require("rosbags")  # the ROS 2 side is an extra: named (exit 2) before anything is read

    out = Path(args.out)
    if out.exists():
        log.error("%s exists: give a new directory for the rosbag2", out)
        return 2
    if not Path(args.recording).is_file():
        log.error("%s: no such recording", args.recording)
        return 2
    from percept.runtime.ros2.bag import export

    try:
        exported = export(args.recording, out, namespace=args.namespace)
    except RecordingError as err:
        log.error("%s", err)
        return 2
    for topic, count in sorted(exported.messages.items()):
        print(f"{topic}: {count} messages")
    if exported.unreadable:
        print(f"skipped {exported.unreadable} world models that could not be read")
    print(f"wrote {out}")
    return 0
