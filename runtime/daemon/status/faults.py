"""What is wrong with a running daemon, in words: the status's ``faults``.

One pure function per source (the drivers, the frames, the peers, the daemon's own messages,
the recording, the network), each from that source's state as the daemon reads it; the daemon
puts them together in this order (:meth:`percept.runtime.daemon.daemon.Daemon.faults`).

Each fault's words stay the same while it lasts: a change of the list publishes the status at
once and is logged, so a number that changes every second (an age, a count) has no place in
them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

from percept.runtime.daemon.status import health
from percept.runtime.record.writer import lost_faults

if TYPE_CHECKING:
    from percept.runtime.incidents import Run
    from percept.runtime.net.codec import JSON
    from percept.runtime.net.link import Traffic


def device_faults(
    camera: Mapping[str, Any],  # the drivers' status(), typed by them
    servos: Mapping[str, Any],
    emulated_servos: bool,
) -> list[str]:
    """The camera's and the servos' faults, from their drivers' status."""
    faults: list[str] = []
    if camera.get("state") != "connected":
        faults.append(f"camera {camera.get('state')}" + health.because(camera.get("error")))
    if servos.get("state") != "connected":
        faults.append(f"servos {servos.get('state')}" + health.because(servos.get("problem")))
    silent = servos.get("not_answering") or {}
    for joint in servos.get("stale") or ():
        if emulated_servos:  # the emulator's thread starved, not a servo failing (its log says)
            faults.append(f"joint {joint} stale (servo emulator): its replies come late")
        else:
            faults.append(f"joint {joint} stale" + health.because(silent.get(joint)))
    for joint, errors in sorted((servos.get("errors") or {}).items()):
        faults.append(f"servo {joint} reports {', '.join(errors)}")
    gaze = servos.get("gaze") or {}
    if gaze.get("state") == "stopped":
        faults.append(f"gaze stopped: {gaze.get('problem')}")
    return faults


def frame_faults(
    ready: bool, since_frame: float, frame_timeout: float, light: Mapping[str, Any] | None
) -> list[str]:
    """The frames' faults: no background yet, frames that stopped coming (none for
    ``since_frame`` seconds), a light the background is adapting to."""
    faults: list[str] = []
    if not ready:
        faults.append("no background model yet")  # the progress is in "background"
    elif since_frame > frame_timeout:
        faults.append(f"no frame for more than {frame_timeout:g} s")
    if light is not None and not light["steady"]:
        faults.append("sudden change of light: the background adapts")
    return faults


def marker_faults(ambiguous_ids: Iterable[int]) -> list[str]:
    """Marker ids seen more than once in an image (called while their count grows)."""
    ids = ", ".join(str(i) for i in sorted(set(ambiguous_ids)))
    return [f"marker ids {ids} seen more than once in an image, not as one box"]


def peer_faults(
    peers: Mapping[str, Mapping[str, JSON]], implausible: Mapping[str, Run], now: float
) -> list[str]:
    """Peers not heard, and peers whose data the arena gate is rejecting."""
    faults = [f"peer {name} not heard" for name, p in sorted(peers.items()) if not p.get("heard")]
    for name, run in sorted(implausible.items()):
        if run.active(now):
            faults.append(f"implausible data from peer {name} rejected: {run.reason}")
    return faults


def unsent_faults(unsent: Mapping[str, Run], now: float) -> list[str]:
    """The daemon's own messages that fail their check, by topic."""
    active = sorted((topic, run.reason) for topic, run in unsent.items() if run.active(now))
    return [f"own {topic} messages fail their check, not sent: {why}" for topic, why in active]


def recording_faults(recording: Mapping[str, JSON] | None, wall: float) -> list[str]:
    """A recording that stopped taking data, and files lost while recording."""
    if recording is None:
        return []
    faults: list[str] = []
    if recording["state"] != "recording":
        faults.append(
            f"recording {recording['state']}: {recording['error']} ({recording['file']}); "
            "goes on in a new file when the disk takes data again"
        )
    faults.extend(lost_faults(recording, wall))
    return faults


def network_faults(
    robot: str,
    clashes: bool,
    traffic: Mapping[str, Traffic],
    prefix: str,
    flood_rate: float,
    dropping: bool,
) -> list[str]:
    """Another process under this robot's name, keys whose messages are being rejected or come
    in floods, received messages dropped (``dropping``: their count grew)."""
    faults: list[str] = []
    if clashes:
        faults.append(f"another process runs as {robot} on the network")
    for key, heard in sorted(traffic.items()):
        if heard.rejected:
            faults.append(f"rejecting messages on {key}: {heard.reason}")
    faults.extend(health.floods(traffic, prefix, flood_rate))
    if dropping:
        faults.append("dropping received messages: they come faster than handled")
    return faults
