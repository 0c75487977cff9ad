"""The daemon on the network: its link opened under its name, what it hears from its peers, and
the games it plays there.

The link is opened before anything else (a name already taken or a port in use ends the start
before a device opens); a link that cannot open names the key or option to change. The peers'
box messages and liveliness changes go through one bounded inbox, so the frames (and a replay)
see them at the same point; only the experiment's robots are peers.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from percept.runtime.daemon.pipeline import Alive, PeerMessage

if TYPE_CHECKING:
    from percept.config.loader import ConfigError
    from percept.runtime.daemon.status.health import Presence
    from percept.runtime.games.language.live import GuessingGames
    from percept.runtime.games.pointing import Located, PointingGames
    from percept.runtime.net.link import Link
    from percept.runtime.net.mailbox import DropOldest
    from percept.runtime.net.messages import Message, PeerPose, World
    from percept.runtime.settings.experiment import Experiment


def open_link(
    experiment: Experiment, robot: str, experiment_path: str | Path, endpoints: Iterable[str]
) -> Link:
    """The robot's link, the only one under its name (``NameTaken`` raised as it is); a link
    that cannot open (a port in use...) is a ``ConfigError`` naming what to change.
    ``endpoints``: the robots whose endpoint ``percept run --endpoint`` gave."""
    from percept.runtime.net.link import Link, LinkError, NameTaken

    try:
        return Link(experiment, robot, exclusive=True)
    except NameTaken:
        raise  # one name, one robot: percept run says so
    except LinkError as err:  # e.g. the port in use: before anything runs, exit 2
        raise _network_error(err, experiment, robot, experiment_path, endpoints) from None


def _network_error(
    err: Exception,
    experiment: Experiment,
    robot: str,
    experiment_path: str | Path,
    endpoints: Iterable[str],
) -> ConfigError:
    """The link could not open: which key or option to change."""
    from percept.config.loader import ConfigError

    if experiment.network.mode == "client":
        return ConfigError(experiment_path, "network.connect", str(err))
    change = "give another port there"
    if robot in endpoints:
        return ConfigError("--endpoint", robot, f"{err}; {change}")
    index = [r.name for r in experiment.robots].index(robot)
    key = f"robots[{index}].endpoint"
    where = "or with percept run --endpoint ROBOT=ENDPOINT"
    return ConfigError(experiment_path, key, f"{err}; {change}, {where}")


def hear_peers(
    link: Link,
    peers: set[str],
    presence: Presence,
    inbox: DropOldest[tuple[float, PeerMessage]],
) -> None:
    """Put the ``peers``' box messages and liveliness changes into ``inbox`` as they arrive
    (with their monotonic arrival time), and keep ``presence`` up to date."""
    from percept.runtime.net.messages import Boxes

    def on_boxes(message: Message) -> None:
        # Only the experiment's robots are peers: another sender would stay "not heard" for
        # ever once it stops. (The link hands on only Boxes on this topic.)
        if isinstance(message, Boxes) and message.robot in peers:
            presence.heard(message.robot)
            inbox.put((time.monotonic(), message))

    def on_alive(name: str, alive: bool) -> None:
        # A peer that exits is gone at once, not stale_after later; through the inbox, so the
        # frames (and a replay) see it at the same point. Only the experiment's robots: any
        # other process's token is nothing to the frames (nor to their record).
        if name not in peers:
            return
        if not alive:
            presence.gone(name)
        inbox.put((time.monotonic(), Alive(name, alive)))

    link.subscribe("boxes", on_boxes)
    link.watch_alive(on_alive)


def open_games(
    link: Link,
    experiment: Experiment,
    world: Callable[[], World | None],
    poses: Callable[[str], PeerPose | None],
) -> tuple[PointingGames, GuessingGames]:
    """The pointing games and the guessing games the robot plays on ``link``, on the last world
    model ``world()`` and the peers' poses; one guessing agent learns across all its games."""
    from percept.runtime.games.language.live import GuessingGames, things
    from percept.runtime.games.pointing import PointingGames, located

    def seen() -> list[Located]:
        last = world()
        return [] if last is None else located(last)

    pointing = PointingGames(
        link,
        world=seen,
        poses=poses,
        settings=experiment.peers,
        players=experiment.players,
    )
    guessing = GuessingGames(
        link,
        things=lambda: things(world()),
        poses=poses,
        settings=experiment.peers,
        players=experiment.players,
    )
    return pointing, guessing


def games_look(experiment: Experiment) -> bool:
    """Whether games from the network may turn the head (``[peers] network_gaze``)."""
    if experiment.peers.network_gaze == "lab":
        return experiment.network.lab
    return True
