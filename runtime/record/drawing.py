"""Pictures of a world model, drawn with OpenCV: anchors over the camera image, the top-down
map (the chapter's Fig. 5.2e and 5.5), and text tables.

Every function takes a world model (:class:`~percept.runtime.net.messages.World`, as the daemon
sends and records it) and returns a new BGR image; nothing here keeps state, so the live view and
the demo's figure draw the same pictures.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from percept.perception.colour import feature_bgr
from percept.runtime.net.messages import ObjectId, World

FONT = cv2.FONT_HERSHEY_SIMPLEX
BLACK = (0, 0, 0)
GREY = (150, 150, 150)
LIGHT = (235, 235, 235)
WHITE = (255, 255, 255)
BOX_COLOUR = (60, 110, 170)  # carton brown, BGR
FALSE_COLOUR = (0, 0, 230)  # red, BGR: a false anchor's cross


BGR = tuple[int, int, int]
#: A point in metres on the map to its pixel.
Pixel = Callable[[float, float], tuple[int, int]]


def object_bgr(features: Mapping[str, float | None]) -> BGR:
    """An object's average colour (BGR) from its luminance, green_red, yellow_blue features."""
    bgr = feature_bgr(*(features.get(k) for k in ("luminance", "green_red", "yellow_blue")))
    return GREY if bgr is None else bgr


def draw_anchors(
    image: np.ndarray, world: World, false: Collection[ObjectId] = frozenset()
) -> np.ndarray:
    """The camera image with each anchor's box in its average colour and its id (Fig. 5.3h);
    an object not seen in the frame (remembered) thin, its id in parentheses; the anchors whose
    ids are in ``false`` (matched to no true object) crossed out in red."""
    out = image.copy()
    for obj in world.objects:
        left, top, w, h = (round(v) for v in obj.bbox)
        colour = object_bgr(obj.features)
        if obj.visible:
            cv2.rectangle(out, (left, top), (left + w, top + h), WHITE, 3)
        cv2.rectangle(out, (left, top), (left + w, top + h), colour, 2 if obj.visible else 1)
        if obj.id in false:
            cv2.line(out, (left, top), (left + w, top + h), FALSE_COLOUR, 2, cv2.LINE_AA)
            cv2.line(out, (left + w, top), (left, top + h), FALSE_COLOUR, 2, cv2.LINE_AA)
        label = str(obj.id) if obj.visible else f"({obj.id})"
        label += " *" if obj.in_motion else ""
        _text(out, label, (left, max(10, top - 4)), 0.4, colour, outline=True)
    return out


@dataclass(frozen=True)
class MapMark:
    """Something drawn on the map besides the world model (ground truth): a hollow circle of
    ``radius`` metres in ``bgr`` at ``(x, y)`` in the robot's ground frame, or an arrow with
    ``theta``."""

    x: float
    y: float
    bgr: BGR = GREY
    radius: float = 0.0
    theta: float | None = None
    label: str = ""


def draw_map(
    world: World | None,
    size: int = 360,
    truth: Sequence[MapMark] = (),
    min_extent: float = 1.0,
    false: Collection[ObjectId] = frozenset(),
) -> np.ndarray:
    """Top-down map in the robot's ground frame (x forward = up, y left = left): the robot at
    its origin as a black arrow, objects as discs in their colour (diameter = width), those not
    seen in the frame (remembered out of sight) as thick rings, boxes as brown squares, peers as
    black arrows; ``truth`` marks drawn as thin rings underneath; the objects whose ids are in
    ``false`` (false anchors) crossed out in red.
    The view fits everything, at least ``min_extent`` metres around the robot. Without a world
    model (None) only the robot and ``truth`` are drawn."""
    objects = () if world is None else world.objects
    # Where each object with a ground position is (x and y are known or unknown together).
    placed = [
        (o, (x, y))
        for o in objects
        if (x := o.features.get("x")) is not None and (y := o.features.get("y")) is not None
    ]
    peers = [] if world is None else list(world.peers.items())
    boxes = () if world is None else world.boxes
    points = [(0.0, 0.0)]
    points += [xy for _, xy in placed]
    points += [(p.x, p.y) for _, p in peers] + [(b.x, b.y) for b in boxes]
    points += [(m.x, m.y) for m in truth]
    view = _MapView.fitting(points, size, min_extent)
    px, span = view.px, view.span
    out = np.full((size, size, 3), 250, np.uint8)
    step = _draw_grid(out, view)
    _draw_truth(out, view, truth)
    for b in boxes:
        _box(out, px, b.x, b.y, b.theta, 0.2, BOX_COLOUR)
        u, v = px(b.x, b.y)
        _text(out, f"box {b.id}", (u + 8, v - 8), 0.35, BOX_COLOUR)
    for o, xy in placed:
        f = o.features
        r = max(3, round((f.get("width") or 0.0) / 2 * view.scale))
        centre = px(*xy)
        if o.visible:
            cv2.circle(out, centre, r, object_bgr(f), -1, cv2.LINE_AA)
        else:  # hollow, inside a black outline like the discs'
            cv2.circle(out, centre, max(1, r - 2), object_bgr(f), 3, cv2.LINE_AA)
        cv2.circle(out, centre, r, BLACK, 1, cv2.LINE_AA)
        if o.id in false:
            (u, v), d = centre, r + 2
            cv2.line(out, (u - d, v - d), (u + d, v + d), FALSE_COLOUR, 2, cv2.LINE_AA)
            cv2.line(out, (u + d, v - d), (u - d, v + d), FALSE_COLOUR, 2, cv2.LINE_AA)
        label = str(o.id) if o.visible else f"({o.id})"
        _text(out, label, (centre[0] + r + 2, centre[1] + 4), 0.35, BLACK)
    _arrow(out, px, 0.0, 0.0, 0.0, span, BLACK, 2)
    robot = "" if world is None else world.robot
    _text(out, robot, (px(0, 0)[0] + 6, px(0, 0)[1] + 14), 0.45, BLACK)
    for name, p in peers:
        _arrow(out, px, p.x, p.y, p.theta, span, BLACK, 2)
        u, v = px(p.x, p.y)
        _text(out, name, (u + 6, v + 14), 0.45, BLACK)
    _text(out, f"grid {step:g} m; x forward, y left, metres", (6, size - 8), 0.35, GREY)
    return out


@dataclass(frozen=True)
class _MapView:
    """The map's window on the ground: ``lo`` and ``hi`` corners (x, y) in metres, the ``span``
    its square side covers and the pixels per metre."""

    size: int
    lo: tuple[float, float]
    hi: tuple[float, float]
    span: float
    scale: float

    @classmethod
    def fitting(
        cls, points: Sequence[tuple[float, float]], size: int, min_extent: float
    ) -> _MapView:
        """The view that shows all ``points``, at least ``min_extent`` metres around the robot."""
        xs, ys = np.array(points).T
        lo_x, hi_x = min(xs.min(), -0.2), max(xs.max(), min_extent)
        lo_y, hi_y = min(ys.min(), -min_extent / 2), max(ys.max(), min_extent / 2)
        span = max(hi_x - lo_x, hi_y - lo_y) * 1.15 + 0.2
        return cls(size, (lo_x, lo_y), (hi_x, hi_y), span, size / span)

    def px(self, x: float, y: float) -> tuple[int, int]:  # a Pixel
        cx_m, cy_m = (self.hi[0] + self.lo[0]) / 2, (self.hi[1] + self.lo[1]) / 2
        half = self.size / 2
        return (round(half - (y - cy_m) * self.scale), round(half - (x - cx_m) * self.scale))


def _draw_grid(out: np.ndarray, view: _MapView) -> float:
    """Grid lines under the whole view, each numbered in metres (x forward along the right
    edge, y left along the top edge); returns their spacing in metres."""
    step = 0.5 if view.span < 6 else 1.0
    lo, hi, px = min(view.lo), max(view.hi), view.px
    size = out.shape[0]
    for k in range(math.floor((lo - view.span) / step), math.ceil((hi + view.span) / step)):
        cv2.line(out, px(k * step, -100), px(k * step, 100), LIGHT, 1)
        cv2.line(out, px(-100, k * step), px(100, k * step), LIGHT, 1)
        row, column = px(k * step, 0)[1], px(0, k * step)[0]
        if 12 <= row < size - 16:
            _text(out, f"x {k * step:g}", (size - 36, row - 2), 0.3, GREY)
        if 40 <= column < size - 40:
            _text(out, f"y {k * step:g}", (column + 2, 10), 0.3, GREY)
    return step


def _draw_truth(out: np.ndarray, view: _MapView, truth: Sequence[MapMark]) -> None:
    px = view.px
    for m in truth:
        if m.theta is None:
            r = max(3, round(m.radius * view.scale))
            cv2.circle(out, px(m.x, m.y), r, m.bgr, 1, cv2.LINE_AA)
        else:
            _arrow(out, px, m.x, m.y, m.theta, view.span, m.bgr, 1)
        if m.label:
            u, v = px(m.x, m.y)
            _text(out, m.label, (u + 6, v + 12), 0.33, GREY)


def _arrow(
    out: np.ndarray,
    px: Pixel,
    x: float,
    y: float,
    theta: float,
    span: float,
    colour: BGR,
    thickness: int,
) -> None:
    length = span * 0.08
    tip = (x + length * math.cos(theta), y + length * math.sin(theta))
    cv2.arrowedLine(out, px(x, y), px(*tip), colour, thickness, cv2.LINE_AA, tipLength=0.45)


def _box(
    out: np.ndarray, px: Pixel, x: float, y: float, theta: float, side: float, colour: BGR
) -> None:
    c, s, h = math.cos(theta), math.sin(theta), side / 2
    corners = [
        (x + c * dx - s * dy, y + s * dx + c * dy)
        for dx, dy in ((h, h), (h, -h), (-h, -h), (-h, h))
    ]
    pts = np.array([px(a, b) for a, b in corners], dtype=np.int32)
    cv2.polylines(out, [pts], True, colour, 2, cv2.LINE_AA)
    cv2.line(out, px(x, y), px(x + c * h, y + s * h), colour, 2, cv2.LINE_AA)


def draw_table(
    header: Sequence[str],
    rows: Iterable[Sequence[str]],
    widths: Sequence[int],
    row_colours: Sequence[BGR | None] | None = None,
    line: int = 16,
) -> np.ndarray:
    """A text table on white: ``header`` bold, then ``rows``; ``widths`` in pixels per column;
    ``row_colours`` marks a row with a colour swatch in its first column."""
    rows = [list(r) for r in rows]
    colours = list(row_colours or [None] * len(rows))
    out = np.full((line * (len(rows) + 1) + 8, sum(widths) + 8, 3), 255, np.uint8)
    x = 4
    for text, w in zip(header, widths, strict=True):
        _text(out, text, (x, line - 3), 0.4, BLACK, thick=True)
        x += w
    cv2.line(out, (0, line + 1), (out.shape[1], line + 1), BLACK, 1)
    for i, (row, colour) in enumerate(zip(rows, colours, strict=True)):
        y = line * (i + 2) - 3
        x = 4
        if colour is not None:
            cv2.rectangle(out, (x, y - 9), (x + 9, y), colour, -1)
            cv2.rectangle(out, (x, y - 9), (x + 9, y), BLACK, 1)
        for j, (text, w) in enumerate(zip(row, widths, strict=True)):
            _text(out, text, (x + (13 if j == 0 and colour is not None else 0), y), 0.38, BLACK)
            x += w
    return out


def stack(images: Sequence[np.ndarray], axis: int, gap: int = 8) -> np.ndarray:
    """Images side by side (``axis`` 1) or one above the other (0), padded white, centred."""
    size = max(im.shape[1 - axis] for im in images)
    parts = []
    for i, im in enumerate(images):
        pad = size - im.shape[1 - axis]
        before, after = pad // 2, pad - pad // 2
        if axis == 1:
            im = cv2.copyMakeBorder(im, before, after, 0, 0, cv2.BORDER_CONSTANT, value=WHITE)
        else:
            im = cv2.copyMakeBorder(im, 0, 0, before, after, cv2.BORDER_CONSTANT, value=WHITE)
        parts.append(im)
        if i < len(images) - 1:
            shape = (size, gap, 3) if axis == 1 else (gap, size, 3)
            parts.append(np.full(shape, 255, np.uint8))
    return np.concatenate(parts, axis=axis)


def caption(image: np.ndarray, text: str) -> np.ndarray:
    """``image`` with a line of text above it."""
    bar = np.full((22, image.shape[1], 3), 255, np.uint8)
    _text(bar, text, (4, 16), 0.5, BLACK, thick=True)
    return np.concatenate([bar, image], axis=0)


def _text(
    out: np.ndarray,
    text: str,
    org: tuple[int, int],
    scale: float,
    colour: BGR,
    thick: bool = False,
    outline: bool = False,
) -> None:
    if outline:
        cv2.putText(out, text, org, FONT, scale, WHITE, 3, cv2.LINE_AA)
    cv2.putText(out, text, org, FONT, scale, colour, 2 if thick else 1, cv2.LINE_AA)
