"""``percept run``: the onboard daemon of one robot (see :mod:`percept.runtime.daemon.daemon`)."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from percept.runtime.daemon.stopping import StopRequest
    from percept.runtime.settings.experiment import Experiment

NAME = "run"
HELP = "run the onboard daemon of one robot: camera and servos to world model on Zenoh"

log = logging.getLogger("percept.run")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--robot",
        type=Path,
        metavar="TOML",
        help="platform profile (default: the one the experiment gives this robot)",
    )
    p.add_argument("--experiment", required=True, type=Path, metavar="TOML", help="experiment file")
    p.add_argument(
        "--name",
        metavar="ROBOT",
        help="this robot's name in the experiment (default: the first robot using --robot's "
        "profile, else the first robot)",
    )
    p.add_argument(
        "--sim",
        metavar="SCENE",
        help="no hardware: simulate the scene (name in config/scenes or a .toml path); the "
        "servos are read through the Dynamixel emulator",
    )
    p.add_argument(
        "--sim-epoch",
        type=float,
        metavar="WALL",
        help="wall-clock time (time.time()) at which the simulated scene starts; daemons given "
        "the same epoch see the same scene at the same moment (default: now)",
    )
    p.add_argument("--record", type=Path, metavar="FILE.mcap", help="record to an MCAP file")
    p.add_argument(
        "--raw-images",
        action="store_true",
        help="record camera images uncompressed (bgr8) instead of JPEG: exact replays",
    )
    p.add_argument(
        "--background",
        type=Path,
        metavar="FILE",
        help="background model: loaded if the file exists, else calibrated and saved there",
    )
    p.add_argument(
        "--enable-gaze",
        action="store_true",
        help="move the head (the experiment's [gaze] settings) even though its [gaze] enabled "
        "is false; with --sim the simulated head follows the emulated servos",
    )
    p.add_argument(
        "--prefix",
        metavar="PREFIX",
        help="first part of every Zenoh key instead of the experiment's prefix: runs with "
        "different prefixes never hear each other",
    )
    p.add_argument(
        "--endpoint",
        action="append",
        default=[],
        metavar="ROBOT=ENDPOINT",
        help="the endpoint of ROBOT (tcp/HOST:PORT) instead of the experiment's; repeat for "
        "each robot to move",
    )
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no status line on the terminal (it is shown only when stdout and stderr are one)",
    )
    p.add_argument(
        "--view",
        nargs="?",
        const=8765,
        type=int,
        metavar="PORT",
        help="serve a live Foxglove WebSocket view on 127.0.0.1:PORT (default 8765)",
    )


def run(args: argparse.Namespace) -> int:
    """The daemon until SIGINT or SIGTERM; the exit code (see
    :mod:`percept.runtime.daemon.stopping`)."""
    from percept.runtime.daemon.stopping import StopRequest, finish, run_until_stopped

    stop = StopRequest()
    stop.install()  # first: a signal while the rest loads stops it as well
    log.info("loading %s", args.experiment)
    try:
        code = run_until_stopped(lambda: _run(args, stop), stop)
    except BaseException:  # e.g. a bad configuration: percept's command line says it
        stop.uninstall()
        raise
    return finish(code)


def _run(args: argparse.Namespace, stop: StopRequest) -> int:
    """Load, run the daemon until ``stop``; its code (on the daemon thread)."""
    from percept.config.loader import ConfigError
    from percept.drivers.sim import require_mujoco
    from percept.perception.warm import warm_up_in_background
    from percept.runtime import console
    from percept.runtime.cli import EXIT_CONFIG
    from percept.runtime.daemon.daemon import Daemon
    from percept.runtime.daemon.settings import DaemonOptions
    from percept.runtime.daemon.stopping import EXIT_FAILED
    from percept.runtime.net.link import NameTaken
    from percept.runtime.settings.experiment import load_experiment
    from percept.runtime.settings.scene import find_scene

    experiment = load_experiment(args.experiment)
    name = args.name or _default_name(experiment, args.robot)
    try:
        experiment.robot(name)
    except KeyError:
        names = ", ".join(r.name for r in experiment.robots)
        raise ConfigError(args.experiment, "robots", f"no robot {name!r}; known: {names}") from None
    profile = args.robot or experiment.robot(name).profile
    if args.robot is None and not Path(profile).is_file():
        index = [r.name for r in experiment.robots].index(name)
        raise ConfigError(args.experiment, f"robots[{index}].profile", f"{profile}: file not found")
    _check_output("--record", args.record)
    _check_output("--background", args.background)
    if args.sim is not None:
        require_mujoco()
    options = DaemonOptions(
        robot=name,
        profile_path=profile,
        experiment_path=args.experiment,
        sim_scene=None if args.sim is None else str(find_scene(args.sim)),
        sim_epoch=args.sim_epoch,
        record=args.record,
        raw_images=args.raw_images,
        view_port=args.view,
        background=args.background,
        enable_gaze=args.enable_gaze,
        prefix=args.prefix,
        endpoints=_endpoints(args.endpoint),
    )
    daemon = Daemon(options)  # its files checked before anything runs: see finish()

    def unfinished() -> int | None:  # the code at a stop that did not finish in time
        if daemon.frames == 0:
            daemon.say_no_world_model()
            return None
        return None if daemon.error else 0

    stop.unfinished = unfinished
    if not stop.starting():
        return EXIT_FAILED  # not reached: the signal's handler ends the process
    # The kernels are compiled (once per machine) or loaded from the cache while the devices
    # start; a first frame that comes sooner waits for the kernel it needs (numba's lock). A
    # stop does not wait for it: see finish().
    warm_up_in_background()
    try:
        if not console.wanted(args.quiet):
            code = daemon.run(stop.event)
        else:
            with console.Console(lambda: console.status_line(*daemon.latest())):
                code = daemon.run(stop.event)
    except NameTaken as err:  # one name, one robot: refused before anything was opened
        print(f"percept: robot {name}: {err}", file=sys.stderr)
        code = EXIT_CONFIG
    except ConfigError as err:  # said here, as the command line would: the exit comes next
        print(f"percept: {err}", file=sys.stderr)
        code = EXIT_CONFIG
    return code


def _default_name(experiment: Experiment, profile: Path | None) -> str:
    if profile is not None:
        for r in experiment.robots:
            if Path(r.profile).resolve() == profile.resolve():
                return r.name
    return experiment.robots[0].name


def _endpoints(given: list[str]) -> dict[str, str]:
    """``--endpoint ROBOT=ENDPOINT`` options by robot."""
    from percept.config.loader import ConfigError

    endpoints = {}
    for item in given:
        robot, sep, endpoint = item.partition("=")
        if not (sep and robot and endpoint):
            raise ConfigError("--endpoint", item, "expected ROBOT=ENDPOINT (a=tcp/127.0.0.1:7447)")
        endpoints[robot] = endpoint
    return endpoints


def _check_output(option: str, path: Path | None) -> None:
    """Refuse, before anything starts, a file option naming a folder, a file in a missing
    folder or in one where no file can be created (read-only, not this user's): the recording
    or the calibration would fail only once the devices are open. A ``--background`` that
    exists is only read."""
    from percept.config.loader import ConfigError

    if path is None:
        return
    if path.is_dir():
        raise ConfigError(option, str(path), "is a folder; expected a file name")
    if not path.parent.is_dir():
        raise ConfigError(option, str(path), f"the folder {path.parent} does not exist")
    if option == "--background" and path.exists():
        return
    problem = _cannot_create_in(path.parent)
    if problem is not None:
        raise ConfigError(option, str(path), f"no file can be created in {path.parent}: {problem}")


def _cannot_create_in(folder: Path) -> str | None:
    """Why no file can be created in ``folder`` (a probe file is made and removed), or None."""
    import tempfile

    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".percept-probe-"):
            return None
    except OSError as err:
        return err.strerror or str(err)
