"""The figures of the scene data set and the games, drawn with OpenCV like the rest of percept:
the agreement scatter plots (robot a's scaled value of a feature against robot b's for the same
object) and the thesis-style curves of communicative success, lexicon size and coherence against
the number of games."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from percept.runtime.games.language.agreement import Agreement
from percept.runtime.record.drawing import BLACK, GREY, caption, stack

PANEL = 220  # pixels, side of a scatter panel's plotting area
MARGIN = 30
CURVES = ((170, 60, 20), (30, 130, 220), (40, 150, 40), (140, 40, 150))  # BGR


def _axes(width: int, height: int) -> np.ndarray:
    out = np.full((height + 2 * MARGIN, width + 2 * MARGIN, 3), 255, np.uint8)
    cv2.rectangle(out, (MARGIN, MARGIN), (MARGIN + width, MARGIN + height), BLACK, 1)
    return out


def _text(
    out: np.ndarray, text: str, org: tuple[int, int], colour: tuple[int, int, int] = BLACK
) -> None:
    cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, 0.4, colour, 1, cv2.LINE_AA)


def scatter(name: str, result: Agreement) -> np.ndarray:
    """One feature: a's scaled value (x axis) against b's (y axis), both 0..1, the diagonal."""
    out = _axes(PANEL, PANEL)

    def px(u: float, v: float) -> tuple[int, int]:
        return MARGIN + round(u * PANEL), MARGIN + PANEL - round(v * PANEL)

    cv2.line(out, px(0, 0), px(1, 1), GREY, 1, cv2.LINE_AA)
    for u, v in result.pairs:
        cv2.circle(out, px(u, v), 2, CURVES[0], -1, cv2.LINE_AA)
    _text(out, "robot a", (MARGIN + PANEL // 2 - 25, 2 * MARGIN + PANEL - 8))
    _text(out, "b", (8, MARGIN + PANEL // 2))
    d = "-" if result.d is None else f"{result.d:.3f}"
    r = "-" if result.r is None else f"{result.r:.2f}"
    return caption(out, f"{name}: d {d}  r {r}  n {result.n}")


def agreement_figure(results: Mapping[str, Agreement]) -> np.ndarray:
    """All features' scatter plots, four to a row."""
    panels = [scatter(name, result) for name, result in results.items()]
    rows = [stack(panels[i : i + 4], 1) for i in range(0, len(panels), 4)]
    return stack(rows, 0)


def curves(
    title: str,
    games: Sequence[int],
    series: Mapping[str, Sequence[float]],
    top: float | None = None,
    width: int = 560,
    height: int = 200,
) -> np.ndarray:
    """Lines of ``series`` (name: values at ``games``) on one axis from 0 to ``top`` (default:
    the largest value), the number of games along the bottom."""
    out = _axes(width, height)
    if not games:
        return caption(out, title)
    peak = (
        top if top is not None else max((max(v, default=0.0) for v in series.values()), default=1)
    )
    peak = peak or 1.0
    last = max(games[-1], 1)

    def px(g: float, v: float) -> tuple[int, int]:
        return MARGIN + round(g / last * width), MARGIN + height - round(v / peak * height)

    for k in range(5):
        v = peak * k / 4
        cv2.line(out, px(0, v), px(last, v), (225, 225, 225), 1)
        _text(out, f"{v:g}", (2, px(0, v)[1] + 4))
    _text(out, f"{last} games", (MARGIN + width - 70, 2 * MARGIN + height - 10))
    for i, (name, values) in enumerate(series.items()):
        colour = CURVES[i % len(CURVES)]
        pts = np.array([px(g, v) for g, v in zip(games, values, strict=True)], np.int32)
        cv2.polylines(out, [pts], False, colour, 2, cv2.LINE_AA)
        _text(out, name, (MARGIN + 8 + 150 * i, MARGIN + 14), colour)
    return caption(out, title)
