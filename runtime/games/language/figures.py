"""The figures of the scene data set and the games, drawn with OpenCV like the rest of percept:
the agreement scatter plots (robot a's scaled value of a feature against robot b's for the same
object) and the thesis-style curves of communicative success, lexicon size and coherence against
the number of games."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from percept.runtime.games.language.dataset.agreement import Agreement
from percept.runtime.record.drawing import BLACK, GREY, caption, stack

PANEL = 220  # pixels, side of a scatter panel's plotting area
MARGIN = 40  # room for the axes' values and names
CURVES = ((170, 60, 20), (30, 130, 220), (40, 150, 40), (140, 40, 150))  # BGR


def _axes(width: int, height: int) -> np.ndarray:
    out = np.full((height + 2 * MARGIN, width + 2 * MARGIN, 3), 255, np.uint8)
    cv2.rectangle(out, (MARGIN, MARGIN), (MARGIN + width, MARGIN + height), BLACK, 1)
    return out


def _text(
    out: np.ndarray, text: str, org: tuple[int, int], colour: tuple[int, int, int] = BLACK
) -> None:
    cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, 0.4, colour, 1, cv2.LINE_AA)


def _tick_x(out: np.ndarray, u: int, label: str, height: int) -> None:
    """A tick on the bottom axis at column ``u`` with its value under it."""
    bottom = MARGIN + height
    cv2.line(out, (u, bottom), (u, bottom + 4), BLACK, 1)
    width = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.35, 1)[0][0]
    cv2.putText(
        out,
        label,
        (u - width // 2, bottom + 14),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.35,
        BLACK,
        1,
        cv2.LINE_AA,
    )


def _tick_y(out: np.ndarray, v: int, label: str) -> None:
    """A tick on the left axis at row ``v`` with its value left of it."""
    cv2.line(out, (MARGIN - 4, v), (MARGIN, v), BLACK, 1)
    width = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.35, 1)[0][0]
    cv2.putText(
        out,
        label,
        (MARGIN - 6 - width, v + 4),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.35,
        BLACK,
        1,
        cv2.LINE_AA,
    )


def _text_up(out: np.ndarray, text: str, v: int) -> None:
    """``text`` written upwards at the left edge, centred on row ``v``: a left axis's name."""
    (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
    strip = np.full((h + base + 2, w + 2, 3), 255, np.uint8)
    cv2.putText(strip, text, (1, h + 1), cv2.FONT_HERSHEY_SIMPLEX, 0.4, BLACK, 1, cv2.LINE_AA)
    turned = cv2.rotate(strip, cv2.ROTATE_90_COUNTERCLOCKWISE)
    top = max(0, v - turned.shape[0] // 2)
    region = out[top : top + turned.shape[0], 1 : 1 + turned.shape[1]]
    np.minimum(region, turned[: region.shape[0], : region.shape[1]], out=region)


def scatter(name: str, result: Agreement) -> np.ndarray:
    """One feature: a's scaled value (x axis) against b's (y axis), both 0..1, the diagonal."""
    out = _axes(PANEL, PANEL)

    def px(u: float, v: float) -> tuple[int, int]:
        return MARGIN + round(u * PANEL), MARGIN + PANEL - round(v * PANEL)

    cv2.line(out, px(0, 0), px(1, 1), GREY, 1, cv2.LINE_AA)
    for u, v in result.pairs:
        cv2.circle(out, px(u, v), 2, CURVES[0], -1, cv2.LINE_AA)
    for tick in (0.0, 0.5, 1.0):
        _tick_x(out, px(tick, 0)[0], f"{tick:g}", PANEL)
        _tick_y(out, px(0, tick)[1], f"{tick:g}")
    _text(out, "robot a, scaled", (MARGIN + PANEL // 2 - 45, 2 * MARGIN + PANEL - 4))
    _text_up(out, "robot b, scaled", MARGIN + PANEL // 2)
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
        _tick_y(out, px(0, v)[1], f"{v:.4g}")
        g = round(last * k / 4)
        _tick_x(out, px(g, 0)[0], f"{g}", height)
    _text(out, "games played", (MARGIN + width // 2 - 40, 2 * MARGIN + height - 4))
    for i, (name, values) in enumerate(series.items()):
        colour = CURVES[i % len(CURVES)]
        pts = np.array([px(g, v) for g, v in zip(games, values, strict=True)], np.int32)
        cv2.polylines(out, [pts], False, colour, 2, cv2.LINE_AA)
        _text(out, name, (MARGIN + 8 + 150 * i, MARGIN + 14), colour)
    return caption(out, title)
