"""The shipped experiment made ready for a test's daemons: free ports, absolute profile paths."""

from __future__ import annotations

from pathlib import Path

from tests.support.zenoh_rig import free_port

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENT = ROOT / "config" / "experiments" / "tabletop.toml"


def experiment_copy(tmp: Path, *edits: tuple[str, str]) -> Path:
    """The default experiment with free ports and absolute profile paths, and each ``(old,
    new)`` of ``edits`` replaced (``old`` must be there)."""
    text = EXPERIMENT.read_text()
    for old, new in edits:
        if old not in text:
            raise ValueError(f"{old!r} is not in {EXPERIMENT}")
        text = text.replace(old, new)
    for port in ("7447", "7448"):
        text = text.replace(f"tcp/127.0.0.1:{port}", f"tcp/127.0.0.1:{free_port()}")
    text = text.replace('"../', f'"{EXPERIMENT.parent.parent}/')
    path = tmp / "experiment.toml"
    path.write_text(text)
    return path


def endpoint(experiment: Path, robot: str) -> str:
    from percept.runtime.settings.experiment import load_experiment

    return load_experiment(experiment).robot(robot).endpoint
