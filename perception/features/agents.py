"""Agents, not objects: which anchors are people (or their arms) rather than things to talk about.

An anchor is an agent while its sensory experience is taller on the ground than ``[features]
max_object_height``, or from its birth on when it came into view moving, as a person does: the
anchors are born only where the foreground is still, so a person walking in gets an anchor when
they stop, still cut by the image's border, where moving foreground came in through the border
in several frames a moment before. An object put down by a hand is born clear of the border (the
hand has gone), and one that a turn of the head brings in gets its anchor once whole
(:mod:`.anchors`).

The decision needs the features, so it is made where they are known: the daemon's pipeline asks
:class:`AgentJudge` after each frame's experiences and keeps agents out of the world model's
objects.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from typing import Literal

import numpy as np

from percept.perception.features.experience import SensoryExperience
from percept.perception.segmentation.percepts import PerceptSet
from percept.perception.tracking.anchors import Anchor
from percept.perception.tracking.memory import covered, touches_border
from percept.perception.tracking.motion import Motion

Reason = Literal["tall", "entered_moving"]

ENTRY_SECONDS = 3.0
"""How long moving foreground that came in through the border is remembered: a person walks in
and stops beside the table within a few seconds."""
ENTRY_MOTION = 0.05
"""Fraction of a percept's box that moved for it to be moving foreground."""
ENTRY_OVERLAP = 0.3
"""Fraction of a newborn anchor's box that such foreground covered for it to be what came in."""
ENTRY_FRAMES = 3
"""Frames in which such foreground covered it: someone walking in moves for many frames, an
object that appears at the border (put down there, cut by it) changes the picture in one."""


class AgentJudge:
    """The agents among one camera's anchors, frame after frame. Call :meth:`watch` once per
    frame with its percepts and motion (before the anchors are judged), then :meth:`reason` for
    each anchor with its experience, then :meth:`next_frame` with the anchors still alive."""

    def __init__(self, max_object_height: float, width: int, height: int) -> None:
        self.max_object_height = max_object_height
        self.width, self.height = width, height
        self._entries: deque[tuple[float, np.ndarray]] = deque()
        """(time, boxes) of moving foreground that touched the border, the last few seconds."""
        self._known: set[str] = set()
        self._entered: set[str] = set()
        """Anchors that came into view moving: agents for good."""

    def watch(self, percepts: PerceptSet, motion: Motion, t: float, turned: bool) -> None:
        """Note this frame's moving foreground at the border; not when the camera ``turned``
        since the last frame: a turn brings the scene in through the border, and what remains
        of it after the motion's compensation is no one walking in."""
        while self._entries and t - self._entries[0][0] > ENTRY_SECONDS:
            self._entries.popleft()
        boxes = percepts.boxes
        if turned or not len(boxes):
            return
        edge = boxes[touches_border(boxes, self.width, self.height)]
        if len(edge):
            moving = edge[motion.fraction(edge) > ENTRY_MOTION]
            if len(moving):
                self._entries.append((t, moving))

    def reason(self, anchor: Anchor, experience: SensoryExperience) -> Reason | None:
        """Why ``anchor`` is an agent (None: it is an object)."""
        if anchor.id not in self._known:
            self._known.add(anchor.id)
            if self._came_in_moving(anchor):
                self._entered.add(anchor.id)
        if anchor.id in self._entered:
            return "entered_moving"
        tall = experience.height is not None and experience.height > self.max_object_height
        return "tall" if tall else None

    def _came_in_moving(self, anchor: Anchor) -> bool:
        box = np.array([anchor.bbox], float)
        if anchor.remembered or not touches_border(box, self.width, self.height)[0]:
            return False
        frames = sum(covered(box, boxes).max() >= ENTRY_OVERLAP for _, boxes in self._entries)
        return frames >= ENTRY_FRAMES

    def next_frame(self, alive: Iterable[str]) -> None:
        """Forget the anchors not in ``alive``."""
        keep = set(alive)
        self._known &= keep
        self._entered &= keep
