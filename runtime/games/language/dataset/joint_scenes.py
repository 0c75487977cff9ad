"""The scene data set (SPEC §4.11): random table-top scenes in the simulated world, seen by both
robots' own pipelines.

Each scene puts 2-5 objects from :data:`CATALOGUE` (shapes, colours and sizes) on the floor
between two robots, as in the chapter's set-up: the robots stand 0.55-0.95 m from the middle of
the table-top, 60-150 degrees apart around it, heads still and turned to its middle; two carton
boxes with markers stand beyond the objects where both robots see a marker. The floor is empty at
first, so each robot calibrates its background on it, then the objects are put down one after
another, as an experimenter does (the chapter's perception splits a region of two objects touching
in the image only with the colour models of anchors it already has: objects that all appear in one
frame, one in front of another, would stay one anchor), and each robot's
:class:`~percept.runtime.daemon.pipeline.Pipeline` runs on its camera frames exactly as in the
daemon: forward kinematics, perception, anchors and features, markers and box poses; the robots
trade their box poses (``percept.boxes/1``) and each estimates the other's pose. Nothing of the
truth goes into that. The truth is read only for scoring: which true object each anchor is (its box
against the true visible boxes) and the true features of every object in each robot's frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from percept.drivers.sim.effects import Effects
from percept.drivers.sim.scene import (
    CameraEffects,
    Event,
    Floor,
    JointMotion,
    Light,
    Lighting,
    Scene,
    SimBox,
    SimMarker,
    SimObject,
    SimRobot,
)
from percept.drivers.sim.world import ObjectTruth, SimWorld, Truth
from percept.perception.assignment import linear_sum_assignment
from percept.perception.colour import histogram_means
from percept.perception.features.experience import FEATURES
from percept.perception.landmarks.detection.detector import Marker
from percept.perception.landmarks.settings import LandmarkSettings
from percept.runtime.daemon.pipeline import FrameInputs, FrameOutput, PeerMessage, Pipeline
from percept.runtime.games.language.dataset.records import (
    RobotView,
    SceneObject,
    SceneRecord,
    TrueObject,
)
from percept.runtime.net.messages import Boxes
from percept.runtime.record.scorecard import relative_pose, to_robot, true_width
from percept.runtime.settings.experiment import Experiment
from percept.runtime.settings.profile import PlatformProfile


@dataclass(frozen=True)
class CatalogueItem:
    """A thing in the toy box: its name, shape, size (x, y, height; metres) and RGB colour."""

    label: str
    shape: str
    size: tuple[float, float, float]
    color: tuple[int, int, int]


#: The toy box the scenes draw from: six shapes, sixteen colours, 3-12 cm. Every footprint is
#: round or square: the width of an elongated thing depends on the side it is seen from (a book
#: is 3 cm wide end-on and 12 cm side-on), which no perception can agree on.
CATALOGUE: tuple[CatalogueItem, ...] = (
    CatalogueItem("red-block", "block", (0.04, 0.04, 0.10), (200, 30, 35)),
    CatalogueItem("blue-cylinder", "cylinder", (0.055, 0.055, 0.07), (30, 70, 200)),
    CatalogueItem("yellow-cone", "cone", (0.06, 0.06, 0.08), (230, 200, 20)),
    CatalogueItem("green-slab", "cuboid", (0.08, 0.08, 0.035), (40, 160, 60)),
    CatalogueItem("pink-toy", "toy", (0.06, 0.07, 0.09), (220, 90, 170)),
    CatalogueItem("orange-ball", "ball", (0.06, 0.06, 0.06), (240, 120, 20)),
    CatalogueItem("purple-tower", "cuboid", (0.05, 0.05, 0.12), (120, 50, 160)),
    CatalogueItem("cyan-block", "block", (0.05, 0.05, 0.05), (30, 180, 190)),
    CatalogueItem("grey-barrel", "cylinder", (0.05, 0.05, 0.12), (150, 150, 160)),
    CatalogueItem("navy-toy", "toy", (0.05, 0.06, 0.08), (30, 40, 110)),
    CatalogueItem("white-ball", "ball", (0.08, 0.08, 0.08), (235, 235, 230)),
    CatalogueItem("black-cone", "cone", (0.07, 0.07, 0.11), (35, 35, 40)),
    CatalogueItem("lime-tile", "cuboid", (0.11, 0.11, 0.03), (150, 210, 40)),
    CatalogueItem("brown-block", "block", (0.07, 0.07, 0.07), (120, 70, 35)),
    CatalogueItem("teal-tin", "cylinder", (0.09, 0.09, 0.05), (20, 120, 110)),
    CatalogueItem("red-ball", "ball", (0.045, 0.045, 0.045), (190, 25, 60)),
)

#: Ceiling lights: a lamp straight above and much ambient light, so that an object's sides look
#: alike from every side (a slanted lamp lights one side and leaves the opposite one dark).
LIGHTING = Lighting(
    ambient=(0.5, 0.5, 0.5), lights=(Light(direction=(0.0, 0.0, -1.0), diffuse=(0.5, 0.5, 0.5)),)
)

TABLE_RADIUS = 0.22  # metres: objects stand within this of the middle
SPACING = 0.13  # metres between object centres at least (pointing gates are below half of it)
FLOORS: tuple[Literal["wood", "carpet", "tiles"], ...] = ("wood", "carpet", "tiles")  # one a scene
SETTLE = 6  # frames after the last object is put down (the first is blocked by motion)
STAGGER = 2  # frames between one object put down and the next (its first frame is motion)
MARKER_FRAMES = 3  # of the last frames, searched for markers (box poses averaged over them)


@dataclass(frozen=True)
class CaptureSettings:
    """How scenes are made: the robots' profile, camera noise, object count."""

    names: tuple[str, str]
    profiles: tuple[Path, Path]
    noise: float = 2.0
    flicker: float = 0.02
    objects: tuple[int, int] = (2, 5)


def random_scene(rng: np.random.Generator, index: int, settings: CaptureSettings) -> Scene:
    """One random scene (see the module text); ``index`` names it and seeds its textures."""
    angle_a = float(rng.uniform(-math.pi, math.pi))
    angle_b = angle_a + float(rng.uniform(math.radians(60), math.radians(150))) * rng.choice(
        [-1, 1]
    )
    robots = []
    for name, profile, angle in zip(
        settings.names, settings.profiles, (angle_a, angle_b), strict=True
    ):
        reach = float(rng.uniform(0.55, 0.95))
        tilt = -math.atan2(0.46, reach) + float(rng.uniform(-0.05, 0.05))
        joints = {
            "head_pan": JointMotion(offset=float(rng.uniform(-0.08, 0.08))),
            "head_tilt": JointMotion(offset=tilt),
        }
        pose = (reach * math.cos(angle), reach * math.sin(angle), angle + math.pi)
        robots.append(SimRobot(name=name, profile=profile, pose=pose, joints=joints))
    # The boxes stand beyond the table-top, opposite the robots' middle direction.
    behind = math.atan2(
        math.sin(angle_a) + math.sin(angle_b), math.cos(angle_a) + math.cos(angle_b)
    )
    boxes = []
    for k, side in enumerate((-1, 1)):
        at = behind + math.pi + side * float(rng.uniform(0.3, 0.5))
        reach = float(rng.uniform(0.42, 0.5))
        boxes.append(
            _box(k, reach * math.cos(at), reach * math.sin(at), float(rng.uniform(0, 6.3)))
        )
    count = int(rng.integers(settings.objects[0], settings.objects[1] + 1))
    picks = rng.choice(len(CATALOGUE), size=count, replace=False)
    placed: list[np.ndarray] = []
    while len(placed) < count:
        xy = rng.uniform(-TABLE_RADIUS, TABLE_RADIUS, 2)
        if np.hypot(*xy) <= TABLE_RADIUS and all(np.hypot(*(xy - p)) >= SPACING for p in placed):
            placed.append(xy)
    objects = tuple(
        SimObject(
            id=int(i) + 1,
            shape=CATALOGUE[i].shape,
            size=CATALOGUE[i].size,
            color=CATALOGUE[i].color,
            pose=(float(xy[0]), float(xy[1]), float(rng.uniform(-math.pi, math.pi))),
            name=CATALOGUE[i].label,
            present=False,
        )
        for i, xy in zip(picks, placed, strict=True)
    )
    return Scene(
        name=f"scene-{index}",
        robots=tuple(robots),
        seed=index,
        floor=Floor(texture=FLOORS[int(rng.choice(len(FLOORS)))]),
        camera=CameraEffects(noise=settings.noise, flicker=settings.flicker),
        lighting=LIGHTING,
        objects=objects,
        boxes=tuple(boxes),
        timeline=(),
    )


def _box(k: int, x: float, y: float, yaw: float) -> SimBox:
    """Landmark box ``k + 1`` of the table-top experiment (markers 4k..4k+3 on its sides)."""
    faces = ("front", "left", "back", "right")
    markers = tuple(SimMarker(id=4 * k + i, side=0.1, face=f) for i, f in enumerate(faces))  # type: ignore[arg-type]
    return SimBox(id=k + 1, size=(0.18, 0.18, 0.18), markers=markers, pose=(x, y, yaw))


def boxes_match(landmarks: LandmarkSettings) -> bool:
    """Whether the experiment knows the boxes and markers the scenes place."""
    known = {b.id: {(m.id, m.face) for m in b.markers} for b in landmarks.boxes}
    placed = (_box(k, 0.0, 0.0, 0.0) for k in range(2))
    return all(known.get(b.id) == {(m.id, m.face) for m in b.markers} for b in placed)


class _StillCamera:
    """A robot's camera while nothing moves: the scene is rendered once per still period and the
    camera's noise and flicker applied per frame, which gives exactly the frames
    :meth:`SimWorld.render` gives (the world is a pure function of time), at a fraction of the
    cost. Call :meth:`frames` with times of one still period only."""

    def __init__(self, world: SimWorld, robot: str) -> None:
        self.world, self.robot = world, robot
        self.clean: np.ndarray | None = None
        self._since: float | None = None
        cam = world.camera_model(robot)
        stream = world.robots.index(robot)
        scene = world.scene
        self.effects = Effects(scene.camera, scene.seed, stream, (cam.height, cam.width, 3))

    @property
    def image(self) -> np.ndarray:
        """The clean render behind the last frame given."""
        assert self.clean is not None, "frames() renders before an image is asked for"
        return self.clean

    def frames(self, times: list[float]) -> Iterator[np.ndarray]:
        for t in times:
            if self.clean is None or self._since is None or not self._still(t):
                self.clean = self.world.render(self.robot, t, effects=False)
                self._since = t
            yield self.effects.apply(self.clean, t)

    def _still(self, t: float) -> bool:
        """Whether nothing was put down between the last render and ``t``."""
        assert self._since is not None
        return all(not (self._since < e.t <= t) for e in self.world.scene.timeline)


def markers_seen_by_both(world: SimWorld) -> bool:
    """Whether both robots see a marker (wholly in the image, facing the camera) of the same
    box: what a peer pose needs."""
    views = world.truth(0.0).views.values()
    seen = [{m.box for m in v.markers.values() if m.in_image and m.facing} for v in views]
    return bool(set.intersection(*seen))


class SceneCapture:
    """Makes scene records: scene, both pipelines, the truth. One per data set."""

    def __init__(
        self,
        experiment: Experiment,
        platforms: dict[str, PlatformProfile],
        settings: CaptureSettings,
    ) -> None:
        # The floor is empty while the robots calibrate: the plain mean and deviation (the
        # chapter's estimator) are what the robust one would give, at a fraction of its cost.
        p = experiment.perception
        background = replace(p.background, estimator="mean")
        self.experiment = replace(experiment, perception=replace(p, background=background))
        self.platforms = platforms
        self.settings = settings

    def world(self, rng: np.random.Generator, index: int) -> SimWorld:
        """The simulated world of a random scene whose boxes both robots see (drawn again until
        they do); its objects are put down one every :data:`STAGGER` frames after the
        background calibration."""
        put_down = self.calibration_frames / self.fps
        while True:
            scene = random_scene(rng, index, self.settings)
            events = tuple(
                Event(t=put_down + k * STAGGER / self.fps, action="add", object=o.id)
                for k, o in enumerate(scene.objects)
            )
            world = SimWorld(replace(scene, timeline=events), self.platforms)
            if markers_seen_by_both(world):  # at time 0 the floor holds only the boxes
                return world
            world.close()

    @property
    def fps(self) -> float:
        return self.platforms[self.settings.names[0]].camera.fps

    @property
    def calibration_frames(self) -> int:
        return self.experiment.perception.background.calibration_frames

    def capture(self, rng: np.random.Generator, index: int, seed: int) -> SceneRecord:
        """A random scene, both robots' pipelines run on it; the record with the truth beside
        it."""
        fps, calibrate, names = self.fps, self.calibration_frames, self.settings.names
        with self.world(rng, index) as world:
            settle = SETTLE + STAGGER * (len(world.scene.objects) - 1)
            times = [calibrate / fps + k / fps for k in range(settle)]
            pipes = {name: self._pipeline(world, name) for name in self.settings.names}
            cameras = {name: _StillCamera(world, name) for name in pipes}
            for name, pipe in pipes.items():
                pipe.calibrate(cameras[name].frames([k / fps for k in range(calibrate)]))
            outs: dict[str, FrameOutput] = {}
            found: dict[str, dict[int, list[Marker]]] = {name: {} for name in pipes}
            messages: dict[str, tuple[tuple[float, PeerMessage], ...]] = {
                name: () for name in pipes
            }
            for seq, t in enumerate(times):
                for name, pipe in pipes.items():
                    (image,) = cameras[name].frames([t])
                    inputs = FrameInputs(
                        seq=seq,
                        t=t,
                        wall=t,
                        joints=world.joint_angles(name, t),
                        peer_messages=messages[name],
                        marker_frames=tuple(found[name]),
                    )
                    outs[name] = pipe.step(image, inputs, found[name])
                    # As in the daemon, a frame's markers are applied with a later frame.
                    searched = settle - 1 - MARKER_FRAMES <= seq < settle - 1
                    found[name] = {seq: pipe.boxes.detector.detect(image)} if searched else {}
                if seq == settle - 2:  # the box poses are traded before the last frame
                    for me, other in (names, names[::-1]):
                        boxes = Boxes(other, t, tuple(pipes[other].boxes.boxes(t)))
                        messages[me] = ((t, boxes),)
                else:
                    messages = {name: () for name in pipes}
            truth = world.truth(times[-1])
            labels = {name: world.labels(name, times[-1]) for name in pipes}
            first, second = (
                self._view(name, outs[name], truth, cameras[name].image, labels[name], pipes[name])
                for name in names
            )
        return SceneRecord(index=index, seed=seed, robots=(first, second))

    def _pipeline(self, world: SimWorld, name: str) -> Pipeline:
        cam = world.camera_model(name)
        return Pipeline(
            name,
            self.platforms[name],
            self.experiment,
            cam.width,
            cam.height,
            joint_max_age=math.inf,
        )

    def _view(
        self,
        name: str,
        out: FrameOutput,
        truth: Truth,
        image: np.ndarray,
        labels: np.ndarray,
        pipe: Pipeline,
    ) -> RobotView:
        other = next(n for n in self.settings.names if n != name)
        model = out.world
        # Every frame has joint readings (the world's), so every frame has a world model and a
        # perception result.
        if model is None or out.result is None:
            raise RuntimeError(f"robot {name}: a simulated frame gave no world model")
        visible = {a.id: a.visible for a in out.result.anchors}
        me = truth.robots[name]
        view = truth.views[name]
        true_objects = []
        for oid, obj in truth.objects.items():
            seen = view.objects[oid]
            feats = _true_features(obj, me.pose, me.camera_world.t, image, labels == oid)
            scaled = {
                f: None if v is None else pipe.scaling.stats[f].scale(v) for f, v in feats.items()
            }
            true_objects.append(TrueObject(oid, obj.name, feats, scaled, round(seen.visible, 4)))
        boxes = {oid: v.bbox for oid, v in view.objects.items() if v.bbox is not None}
        which = match_boxes([o.bbox for o in model.objects], boxes)
        objects = tuple(
            SceneObject(
                id=str(o.id),
                features=dict(o.features),
                scaled=dict(o.scaled),
                visible=visible[str(o.id)],
                truth=which[i],
            )
            for i, o in enumerate(model.objects)
        )
        peer = model.peers.get(other)
        estimate = None if peer is None else (peer.x, peer.y, peer.theta)
        return RobotView(
            robot=name,
            objects=objects,
            peer=estimate,
            true_peer=relative_pose(me.pose, truth.robots[other].pose),
            truth=tuple(true_objects),
        )


MATCH_IOU = 0.3  # an anchor is a true object when their boxes overlap this much at least


def match_boxes(
    anchors: Sequence[Sequence[float]], truth: dict[int, tuple[int, int, int, int]]
) -> list[int | None]:
    """For each anchor box, the true object whose visible box it overlaps most (one anchor per
    object, Hungarian on 1 - IoU), or None below :data:`MATCH_IOU`."""
    from percept.perception.evaluation.tracking import iou

    out: list[int | None] = [None] * len(anchors)
    if not anchors or not truth:
        return out
    ids = list(truth)
    overlap = iou(np.array(anchors, float), np.array([truth[i] for i in ids], float))
    rows, cols = linear_sum_assignment(-overlap)
    for r, c in zip(rows, cols, strict=True):
        if overlap[r, c] >= MATCH_IOU:
            out[r] = ids[c]
    return out


def _true_features(
    obj: ObjectTruth,
    pose: tuple[float, float, float],
    camera: np.ndarray,
    image: np.ndarray,
    mask: np.ndarray,
) -> dict[str, float | None]:
    """The seven features a perfect perception would give robot at ``pose`` (world frame; its
    camera at ``camera``): footprint centre in its frame, width across its line of sight,
    height, and the colour of the object's visible pixels (None when none show)."""
    x, y = to_robot(pose, float(obj.position[0]), float(obj.position[1]))
    sight = obj.position[:2] - camera[:2]
    sight = sight / np.linalg.norm(sight)
    feats: dict[str, float | None] = dict.fromkeys(FEATURES)
    feats.update(
        x=x,
        y=y,
        width=true_width(obj.shape, obj.size, obj.R[:2, :2], np.array([-sight[1], sight[0]])),
        height=obj.top,
    )
    if mask.any():
        ycrcb = cv2.cvtColor(image, cv2.COLOR_BGR2YCrCb)
        m = mask.astype(np.uint8)
        h = np.vstack([cv2.calcHist([ycrcb], [c], m, [16], [0, 256]).ravel() for c in range(3)])
        lum, cr, cb = (float(v) for v in histogram_means(h / h.sum(axis=1, keepdims=True)))
        feats.update(luminance=lum, green_red=cr, yellow_blue=cb)
    return feats


def capture_scenes(
    capture: SceneCapture,
    count: int,
    seed: int,
    progress: Callable[[int, int], None] | None = None,
) -> Iterator[SceneRecord]:
    """``count`` scene records from seed ``seed``, one after the other (a generator)."""
    for k in range(count):
        yield capture.capture(np.random.default_rng([seed, k]), k, seed)
        if progress is not None:
            progress(k + 1, count)
