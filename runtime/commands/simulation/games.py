"""``percept games``: a population plays naming or guessing games on a scene data set.

Reads ``DIR/scenes.jsonl`` (made by ``percept scenes``), plays ``--games`` games of ``--agents``
agents on the robots' perceived features or on the true ones, and writes ``OUT/summary.json``
(``success_last_1000``, ``coherence`` (last 1000 games), ``lexicon_size`` and ``categories``
(means per agent at the end), success after 1000, 2500, 10000 and 25000 games, and the curves),
``OUT/success.png``; prints the summary without the curves as one JSON line. See
:mod:`percept.runtime.games.language` for the games.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from percept.runtime.games.language.dataset.contexts import Context
    from percept.runtime.games.language.population import History
    from percept.runtime.net.codec import JSON

NAME = "games"
HELP = "naming or guessing games of a population of agents on a scene data set (percept scenes)"

log = logging.getLogger("percept.games")

MARKS = (1000, 2500, 10000, 25000)  # games after which the success is reported
WINDOW = 1000  # games the success and coherence are measured over


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dir", type=Path, metavar="DIR", help="folder with scenes.jsonl")
    p.add_argument("--game", required=True, choices=["naming", "guessing"], help="which game")
    p.add_argument("--agents", type=int, default=10, metavar="N", help="population (default 10)")
    p.add_argument("--games", type=int, default=25000, metavar="G", help="games (default 25000)")
    p.add_argument(
        "--features",
        choices=["perceived", "truth"],
        default="perceived",
        help="the robots' own perception (default) or the true features",
    )
    p.add_argument("--seed", type=int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument("--out", type=Path, required=True, metavar="OUT", help="output folder")
    p.add_argument(
        "--categories",
        choices=["prototypes", "trees"],
        default="prototypes",
        help="guessing game: prototypes (default) or discrimination trees",
    )
    p.add_argument(
        "--channels",
        help="guessing game: features categories are made on, comma-separated "
        "(default: all but the egocentric x and y)",
    )
    p.add_argument(
        "--gate",
        type=float,
        metavar="M",
        help="metres: a pointed-at place this close to an object is it (default: the "
        "experiment's pointing gate, 0.05)",
    )


def run(args: argparse.Namespace) -> int:
    from percept.config.loader import ConfigError
    from percept.runtime.games.language.dataset.contexts import GATE, SHARED_CHANNELS, contexts
    from percept.runtime.games.language.dataset.records import SceneFileError, read_scenes

    path = args.dir / "scenes.jsonl"
    if not path.is_file():
        raise ConfigError(path, "", "no scenes file (make one with percept scenes)")
    gate = GATE if args.gate is None else args.gate
    wanted = ",".join(SHARED_CHANNELS) if args.channels is None else args.channels
    if args.agents < 2 or args.games < 1 or args.seed < 0 or gate <= 0:
        print("percept games: --agents at least 2, --games at least 1, --seed >= 0, --gate > 0")
        return 2
    channels = tuple(c.strip() for c in wanted.split(",") if c.strip())
    try:
        scenes = list(read_scenes(path))
        found = contexts(
            scenes,
            args.features,
            channels,
            gate,
            least=1 if args.game == "naming" else 2,
        )
    except SceneFileError as err:
        raise ConfigError(path, "", str(err)) from None
    except ValueError as err:
        raise ConfigError("--channels", wanted, str(err)) from None
    if not found:
        raise ConfigError(path, "", "no scene has objects both robots see")
    began, cpu = time.perf_counter(), time.process_time()
    history = _play(args, found, channels)
    seconds, cpu = time.perf_counter() - began, time.process_time() - cpu
    summary: dict[str, JSON] = {
        "game": args.game,
        "features": args.features,
        "agents": args.agents,
        "games": args.games,
        "seed": args.seed,
        "scenes": len(scenes),
        "contexts": len(found),
        "objects_per_context": round(sum(map(len, found)) / len(found), 2),
        "success_last_1000": round(history.success_over(WINDOW), 4),
        "coherence": round(history.coherence[-1], 4),
        "lexicon_size": history.lexicon[-1],
        "categories": history.categories[-1],
        "success_after": {
            str(n): round(history.success_over(WINDOW, n), 4) for n in MARKS if n <= args.games
        },
        "seconds": round(seconds, 2),
        "cpu_seconds": round(cpu, 2),
    }
    if args.game == "guessing":
        summary.update(category_kind=args.categories, channels=list(channels))
    args.out.mkdir(parents=True, exist_ok=True)
    _write(args, summary, history)
    print(json.dumps(summary))
    return 0


def _play(args: argparse.Namespace, found: list[Context], channels: tuple[str, ...]) -> History:
    from percept.runtime.games.language.guessing import GuessingGame, GuessingSettings
    from percept.runtime.games.language.naming import NamingGame
    from percept.runtime.games.language.population import play

    def progress(done: int, total: int) -> None:
        log.info("game %d/%d", done, total)

    # Two calls, not one on either game: the games' agents mean different things (names,
    # categories), so neither game's type covers both.
    rest = (found, args.agents, args.games, args.seed, WINDOW, 100, progress)
    if args.game == "naming":
        _, history = play(NamingGame(), *rest)
    else:
        settings = GuessingSettings(categories=args.categories)
        _, history = play(GuessingGame(len(channels), settings), *rest)
    return history


def _write(args: argparse.Namespace, summary: dict[str, JSON], history: History) -> None:
    """``summary.json`` (the summary and the curves) and ``success.png`` into ``args.out``."""
    import cv2

    from percept.runtime.games.language.figures import curves
    from percept.runtime.record.drawing import stack

    curves_json = {
        "games": history.games,
        "success": [round(v, 4) for v in history.success],
        "coherence": [round(v, 4) for v in history.coherence],
        "lexicon_size": history.lexicon,
        "categories": history.categories,
    }
    (args.out / "summary.json").write_text(
        json.dumps({**summary, "curves": curves_json}, indent=2) + "\n", encoding="utf-8"
    )
    title = f"{args.game} game, {args.agents} agents, {args.features} features"
    rates = curves(
        f"{title}: success, coherence",
        history.games,
        {"communicative success": history.success, "coherence": history.coherence},
        top=1.0,
    )
    sizes = {"lexicon size": history.lexicon}
    if args.game == "guessing":
        sizes["categories"] = history.categories
    figure = stack([rates, curves("words and categories per agent", history.games, sizes)], 0)
    cv2.imwrite(str(args.out / "success.png"), figure)
