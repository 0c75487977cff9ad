"""Agents, not objects: which anchors are people (or their arms) rather than things to talk about.

An anchor is an agent while its sensory experience is taller on the ground than ``[features]
max_object_height``, or while it stands in view (its foot on the ground, the bottom border clear
of it) and reaches out of the view's top: the top border's ray proves only part of its height,
and a person beside the table, taller than a camera looking down at it stands, always reaches
out of the top, where no object on the table does (an object far off at the top of the view may,
until seen whole). And an anchor is an agent once it came into view moving, as a person does,
for as long as the top or a side border cuts it: wholly in view its height decides (an object
that an arm left where it reached in is an object again, a person seen whole is tall), and cut
by the bottom border alone it lies close before the robot, where a hand puts things down (a
person that close reaches out of the top too). The anchors are born where the foreground is
still, so a person walking in gets an anchor cut by the image's border, where moving
foreground came in through the border in several frames of the few seconds around its birth
(mostly before it; after it, when little of the legs that came in moved). An object put down by
a hand is born clear of the border (the hand has gone), and one that a turn of the head brings
in gets its anchor once whole (:mod:`.anchors`).

The height needs the features, so the decision is made where they are known:
:class:`ObjectsAndAgents` gives each frame's anchors their experiences and asks
:class:`AgentJudge`; the daemon's pipeline keeps the agents out of the world model's objects,
and ``percept track`` keeps them out of its tracks.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from percept.perception.compiled.boxes_kernels import border_sides
from percept.perception.segmentation.percepts import PerceptSet
from percept.perception.tracking.anchors import Anchor, coming_into_view
from percept.perception.tracking.motion import Motion
from percept.perception.tracking.permanence.memory import covered, touches_border

if TYPE_CHECKING:
    from percept.kinematics.pose import CameraPose
    from percept.perception.features.experience import SensoryExperience, SensoryMemory
    from percept.perception.pipeline import FrameResult

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
ENTRY_SHARE = 0.6
"""Share of how far a young anchor's box now reaches into the view from the border it was born
at that its box at birth reached, under which it came in moving: the legs of someone walking
towards the camera grow from the border while little of them moves from frame to frame (they
are one colour), where a still object's box stays put and one that an object put down beside
it joins grows along the border, not into the view."""


class AgentJudge:
    """The agents among one camera's anchors, frame after frame. Call :meth:`watch` once per
    frame with its percepts and motion (before the anchors are judged), then :meth:`reason` for
    each anchor with its experience, then :meth:`next_frame` with the anchors still alive."""

    def __init__(self, max_object_height: float, width: int, height: int) -> None:
        self.max_object_height = max_object_height
        self.width, self.height = width, height
        self._entries: deque[tuple[float, np.ndarray]] = deque()
        """(time, boxes) of moving foreground that touched the border, the last few seconds."""
        self._entered: set[str] = set()
        """Anchors that came into view moving, agents while the border cuts them."""
        self._born: dict[str, np.ndarray | None] = {}
        """Each anchor's box at its first sight when that was at the border (else None)."""
        self._brought: set[str] = set()
        """Young anchors whose border a turn of the camera has brought the scene in through."""
        self._above: set[str] = set()
        """Anchors seen standing in view (their foot on the ground) and reaching out of its top,
        agents while the top border cuts them: taller than the view shows."""

    def watch(
        self, percepts: PerceptSet, motion: Motion, t: float, turn: np.ndarray | None
    ) -> None:
        """Note this frame's moving foreground at the border; not when the camera turned since
        the last frame (``turn``: the view's change, the last frame's pixels to this one's, as
        :attr:`.anchors.AnchorTracker.turn`; None: it did not turn): a turn brings the scene in
        through the border, and what remains of it after the motion's compensation is no one
        walking in. A young anchor born at a border through which the turn brings the scene in
        may grow without having moved."""
        while self._entries and t - self._entries[0][0] > ENTRY_SECONDS:
            self._entries.popleft()
        if turn is not None:
            ids = [i for i, box in self._born.items() if box is not None]
            if ids:
                born = np.array([self._born[i] for i in ids], float)
                brought = coming_into_view(born, turn, self.width, self.height)
                self._brought.update(i for i, b in zip(ids, brought, strict=True) if b)
        boxes = percepts.boxes
        if turn is not None or not len(boxes):
            return
        edge = boxes[touches_border(boxes, self.width, self.height)]
        if len(edge):
            moving = edge[motion.fraction(edge) > ENTRY_MOTION]
            if len(moving):
                self._entries.append((t, moving))

    def reason(self, anchor: Anchor, height: float | None) -> Reason | None:
        """Why ``anchor``, standing ``height`` metres tall on the ground as far as it is in
        view (its sensory experience's; None: not known, as without a camera pose), is an agent
        (None: it is an object)."""
        if anchor.id not in self._entered and self._came_in_moving(anchor):
            self._entered.add(anchor.id)
        top, bottom, left, right = border_sides(*anchor.bbox, self.width, self.height)
        if anchor.id in self._entered:
            if anchor.remembered or top or left or right:
                return "entered_moving"
            # Wholly in view, or cut by the bottom border alone, it is no longer what came in
            # cut by the border: the object an arm left where it reached in (before the robot,
            # where the bottom border cuts what lies close), or a person whom their height now
            # tells (a person close enough to be cut by the bottom reaches out of the top too).
            self._entered.discard(anchor.id)
        if height is None:
            return None
        if top and not bottom and not anchor.remembered:
            self._above.add(anchor.id)
        if anchor.id in self._above:
            if anchor.remembered or top:
                return "tall"
            self._above.discard(anchor.id)  # (seen to its top: its height tells)
        return "tall" if height > self.max_object_height else None

    def _came_in_moving(self, anchor: Anchor) -> bool:
        """At an anchor's first sight at the border: whether moving foreground came in through
        it where the anchor is, in several frames before. Then, while it is young: whether its
        box has grown into the view from there, the camera still; one born a frame or two after
        a person's legs came in (too little of them moved to hold the birth back) has the rest
        of the walk in to show that it came in moving."""
        box = np.array(anchor.bbox, float)
        if anchor.id not in self._born:
            size = self.width, self.height
            at_border = not anchor.remembered and touches_border(box[None], *size)[0]
            self._born[anchor.id] = box if at_border else None
            if not at_border:
                return False
            cover = (covered(box[None], boxes).max() for _, boxes in self._entries)
            return sum(c >= ENTRY_OVERLAP for c in cover) >= ENTRY_FRAMES
        born = self._born[anchor.id]
        if born is None or anchor.remembered or anchor.age > ENTRY_SECONDS:
            return False
        if anchor.id in self._brought:  # (the view grew it: no sign of a walk)
            return False
        return bool(np.any(self._reach(born, born) < ENTRY_SHARE * self._reach(box, born)))

    def _reach(self, box: np.ndarray, born: np.ndarray) -> np.ndarray:
        """How far ``box`` reaches into the view from each border that ``born`` touches (from
        the top, bottom, left and right border; NaN for a border it does not touch)."""
        left, top, width, height = (float(v) for v in born)
        touches = np.array(border_sides(left, top, width, height, self.width, self.height), bool)
        x, y, w, h = box
        reach = np.array([y + h, self.height - y, x + w, self.width - x], float)
        return np.where(touches, reach, np.nan)

    def next_frame(self, alive: Iterable[str]) -> None:
        """Forget the anchors not in ``alive``."""
        keep = set(alive)
        self._entered &= keep
        self._born = {i: box for i, box in self._born.items() if i in keep}
        self._brought &= keep
        self._above &= keep


@dataclass(frozen=True)
class Sorted:
    """One anchor of a frame: its sensory experience (None without a camera pose) and why it is
    an agent (None: an object)."""

    anchor: Anchor
    experience: SensoryExperience | None
    reason: Reason | None


class ObjectsAndAgents:
    """Each frame's anchors with their sensory experiences, sorted into objects and agents: the
    one order of :class:`AgentJudge`'s calls and of the experiences' memory that the daemon's
    pipeline and ``percept track`` share. ``memory`` None: no experiences (no camera model), so
    only what came into view moving is an agent."""

    def __init__(self, judge: AgentJudge, memory: SensoryMemory | None) -> None:
        self.judge = judge
        self.memory = memory

    def sort(
        self, result: FrameResult, pose: CameraPose | None, turn: np.ndarray | None
    ) -> list[Sorted]:
        """``result``'s anchors seen from ``pose`` (None: not known, no experiences), in their
        order; ``turn``: the view's change since the last frame (None: the camera did not
        turn)."""
        if result.masks is not None:
            self.judge.watch(result.percept_set, result.masks.moved, result.t, turn)
        out = []
        for anchor in result.anchors:
            exp = None
            if self.memory is not None and pose is not None:
                exp = self.memory.of_anchor(anchor, pose)
            height = None if exp is None else exp.height
            out.append(Sorted(anchor, exp, self.judge.reason(anchor, height)))
        alive = [a.id for a in result.anchors]
        if self.memory is not None:
            self.memory.next_frame(alive)
        self.judge.next_frame(alive)
        return out
