"""The simulated world at any scene time: each robot's camera image and the ground truth.

Nothing in the world is integrated over time: robot joints follow their scene motion, objects
their timeline, so the state at time ``t`` is a pure function of ``t`` and the scene. Frames and
truth are therefore the same in every run and can be produced in any order. Camera noise and
flicker are drawn from a generator seeded by (scene seed, robot, time).

Truth per camera comes from segmentation renders: an object's visible pixels are those labelled
with it in a render of the whole scene; its unoccluded outline comes from a render of the object
alone (only done when something could be hiding part of it: when its visible pixels touch another
thing's, or when none are visible though its bounding box lies in the view). ``visible`` is the
ratio of the two counts. An object cut off by the image border counts only its pixels inside the
image in both, so ``visible`` measures occlusion, not truncation.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
from collections.abc import Iterable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import cv2
import mujoco
import numpy as np

from percept.drivers.sim.effects import Effects, motion_blur
from percept.drivers.sim.light import levels
from percept.drivers.sim.model import (
    BOX_LABEL,
    CAMERA_FROM_MJCAM,
    ROBOT_LABEL,
    SOLO_GROUP,
    RobotModel,
    RobotPlatform,
    build_model,
)
from percept.drivers.sim.scene import Scene
from percept.drivers.sim.timeline import compile_timeline
from percept.kinematics.camera import CameraModel
from percept.kinematics.pose import CameraPose, ground_pose, ground_transform, invert, marker_on_box

log = logging.getLogger("percept.sim")

BBox = tuple[int, int, int, int]  # left, top, width, height in pixels (0-based, OpenCV)
_AWAY = np.array([0.0, 0.0, -1000.0])  # where absent objects wait: beyond the far clip plane
_SOLO_CACHE = 1024  # unoccluded outlines remembered (objects x camera poses)
_MARKER_CORNERS = np.array([[-1, 1], [1, 1], [1, -1], [-1, -1]], dtype=float) / 2  # TL TR BR BL


def _bbox(mask: np.ndarray) -> BBox | None:
    """The bounding box of the true pixels of ``mask``, or None when there are none."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask.any(axis=0))
    return (int(cols[0]), int(rows[0]), int(cols[-1] - cols[0] + 1), int(rows[-1] - rows[0] + 1))


def _may_show(uv: np.ndarray, lens: CameraModel) -> bool:
    """Whether points projected to ``uv`` (NaN behind the camera) may cover part of the image."""
    front = np.isfinite(uv[:, 0])
    if not front.all():
        return bool(front.any())  # partly behind the lens: its outline is unbounded
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    return bool(hi[0] >= -0.5 and hi[1] >= -0.5 and lo[0] < lens.width and lo[1] < lens.height)


@dataclass(frozen=True)
class ObjectTruth:
    """Where an object is: ``R`` turns its frame into the world frame, ``position`` is the centre
    of its bounding box; ``size`` its bounding box in its own frame; ``top`` its highest point."""

    id: int
    name: str
    shape: str
    color: tuple[int, int, int]
    size: tuple[float, float, float]
    position: np.ndarray
    R: np.ndarray
    standing: bool
    top: float

    @property
    def yaw(self) -> float:
        """Heading of its own x axis on the floor (of its z axis when that lies flat)."""
        axis = self.R[:, 0] if abs(self.R[2, 0]) < 0.99 else self.R[:, 2]
        return math.atan2(float(axis[1]), float(axis[0]))


@dataclass(frozen=True)
class ObjectView:
    """An object in one camera image: ``bbox`` of its visible pixels, ``bbox_full`` of its
    unoccluded outline (both within the image), ``pixels`` visible, ``visible`` the fraction of
    its unoccluded pixels that are visible (0 when it is not in the image at all)."""

    id: int
    bbox: BBox | None
    bbox_full: BBox | None
    pixels: int
    visible: float


@dataclass(frozen=True)
class MarkerView:
    """A marker's black-square corners in one camera image (top-left, top-right, bottom-right,
    bottom-left as cv2.aruco reports them), whether its face turns towards the camera, and
    whether all four corners fall inside the image."""

    id: int
    box: int
    corners: np.ndarray
    facing: bool
    in_image: bool


@dataclass(frozen=True)
class RobotTruth:
    """A robot: its ground pose in the world, its joint angles, and its camera's pose in its own
    ground frame (``camera``, what forward kinematics should give) and in the world."""

    name: str
    pose: tuple[float, float, float]
    joints: dict[str, float]
    camera: CameraPose
    camera_world: CameraPose

    def matrix(self) -> np.ndarray:
        """4x4 world <- this robot's ground frame."""
        return ground_transform(*self.pose)


@dataclass(frozen=True)
class View:
    """What one robot's camera sees: objects, boxes, their markers, and the other robots."""

    robot: str
    objects: dict[int, ObjectView]
    boxes: dict[int, tuple[BBox | None, int]]
    markers: dict[int, MarkerView]
    robots: dict[str, tuple[BBox | None, int]]


@dataclass(frozen=True)
class Truth:
    """The whole truth at scene time ``t``; ``views`` for the cameras asked for."""

    t: float
    objects: dict[int, ObjectTruth]
    boxes: dict[int, tuple[float, float, float]]
    robots: dict[str, RobotTruth]
    views: dict[str, View]

    def record(self, robot: str) -> dict[str, Any]:
        """A JSON-able record of the truth as robot ``robot`` should perceive it: world poses,
        and the same things in its ground frame (``ground``), its camera pose and its view."""
        me = self.robots[robot]
        to_me = invert(me.matrix())
        view = self.views[robot]
        return {
            "t": round(self.t, 6),
            "robot": robot,
            "pose": [round(v, 6) for v in me.pose],
            "joints": {k: round(v, 6) for k, v in me.joints.items()},
            "camera": me.camera.as_dict(),
            "camera_world": {**me.camera_world.as_dict(), "frame": "world"},
            "objects": [
                _object_record(o, view.objects[o.id], to_me) for o in self.objects.values()
            ],
            "boxes": [_box_record(b, pose, view, to_me) for b, pose in self.boxes.items()],
            "robots": [_robot_record(r, view, to_me) for r in self.robots.values()],
        }


def _in_ground(to_me: np.ndarray, T: np.ndarray) -> list[float]:
    """The ground pose (x, y, yaw) of world pose ``T`` in the frame ``to_me`` maps the world to."""
    return [round(v, 6) for v in ground_pose(to_me @ T)]


def _object_record(o: ObjectTruth, seen: ObjectView, to_me: np.ndarray) -> dict[str, Any]:
    """An object's entry in :meth:`Truth.record`: where it is and how the camera sees it."""
    here = np.eye(4)
    here[:3, 3] = (o.position[0], o.position[1], 0.0)
    return {
        "id": o.id,
        "name": o.name,
        "shape": o.shape,
        "color": list(o.color),
        "size": list(o.size),
        "position": [round(float(v), 6) for v in o.position],
        "yaw": round(o.yaw, 6),
        "R": [[round(float(v), 6) for v in row] for row in o.R],
        "standing": o.standing,
        "top": round(o.top, 6),
        "ground": _in_ground(to_me, here)[:2],
        "bbox": list(seen.bbox) if seen.bbox else None,
        "bbox_full": list(seen.bbox_full) if seen.bbox_full else None,
        "pixels": seen.pixels,
        "visible": round(seen.visible, 4),
    }


def _box_record(
    box_id: int, pose: tuple[float, float, float], view: View, to_me: np.ndarray
) -> dict[str, Any]:
    """A box's entry in :meth:`Truth.record`, with its markers as the camera sees them."""
    bbox, pixels = view.boxes[box_id]
    markers = [
        {
            "id": m.id,
            "corners": [[round(float(v), 3) for v in c] for c in m.corners],
            "facing": m.facing,
            "in_image": m.in_image,
        }
        for m in view.markers.values()
        if m.box == box_id
    ]
    return {
        "id": box_id,
        "pose": [round(v, 6) for v in pose],
        "ground": _in_ground(to_me, ground_transform(*pose)),
        "bbox": list(bbox) if bbox else None,
        "pixels": pixels,
        "markers": markers,
    }


def _robot_record(other: RobotTruth, view: View, to_me: np.ndarray) -> dict[str, Any]:
    """A robot's entry in :meth:`Truth.record`; how it looks only for another robot's view."""
    entry: dict[str, Any] = {
        "name": other.name,
        "pose": [round(v, 6) for v in other.pose],
        "ground": _in_ground(to_me, other.matrix()),
    }
    if other.name != view.robot:
        bbox, pixels = view.robots[other.name]
        entry.update(bbox=list(bbox) if bbox else None, pixels=pixels)
    return entry


class SimWorld:
    """A scene in MuJoCo: render any robot's camera at any scene time, and tell the truth.

    Thread-safe: any thread may call (one lock; all OpenGL work happens on one thread of the
    world's own). Call :meth:`close` (or use it as a context manager) to free the GL contexts.
    """

    def __init__(self, scene: Scene, platforms: Mapping[str, RobotPlatform]) -> None:
        self.scene = scene
        self.spec = build_model(scene, platforms)
        self.model = self.spec.compile()
        self.data = mujoco.MjData(self.model)
        self.tracks = compile_timeline(scene)
        self._levels = levels(scene)
        self._diffuse = self.model.light_diffuse.copy()  # the scene's own, scaled by `lights`
        self._ambient = self.model.vis.headlight.ambient.copy()
        self._lock = threading.RLock()
        self._time: float | None = None
        # One renderer per image size, shared by the cameras of that size (a renderer is a GL
        # context, the costliest part of opening a world); used on the GL thread only.
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._gl: ThreadPoolExecutor | None = None
        self._camera_effects: dict[str, Effects] = {}
        self._followed: dict[str, dict[str, float]] = {}  # joint angles from servos, by robot
        m = self.model
        self._mocap = {
            o.id: int(m.body_mocapid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"obj{o.id}")])
            for o in scene.objects
        }
        self._qpos = {
            name: {
                joint: int(m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, mj)])
                for joint, mj in rm.joints.items()
            }
            for name, rm in self.spec.robots.items()
        }
        self._camera_id = {
            name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, rm.camera)
            for name, rm in self.spec.robots.items()
        }
        self._geom_label = np.zeros(m.ngeom + 1, dtype=np.int64)  # index objid + 1; -1 -> 0
        self._object_geoms: dict[int, list[int]] = {o.id: [] for o in scene.objects}
        for name, label in self.spec.labels.items():
            gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
            self._geom_label[gid + 1] = label
            if label in self._object_geoms:
                self._object_geoms[label].append(gid)
        self._options: dict[str, mujoco.MjvOption] = {}
        for name, rm in self.spec.robots.items():
            option = mujoco.MjvOption()
            option.geomgroup[:] = 1
            option.geomgroup[rm.group] = 0
            option.geomgroup[SOLO_GROUP] = 0
            self._options[name] = option
        self._solo_cache: dict[tuple, tuple[int, BBox | None]] = {}
        self._solo = mujoco.MjvOption()
        self._solo.geomgroup[:] = 0
        self._solo.geomgroup[SOLO_GROUP] = 1

    # -- context ----------------------------------------------------------------------------------

    def close(self) -> None:
        """Free the rendering contexts (rendering again opens new ones)."""
        with self._lock:
            if self._gl is None:
                return
            self._gl.submit(self._free).result()
            self._gl.shutdown()
            self._gl = None

    def __del__(self) -> None:
        # The GL contexts must be freed on the thread that used them, not by the garbage
        # collector's thread; at interpreter exit that thread may be gone: the process frees them.
        with contextlib.suppress(RuntimeError, AttributeError):
            self.close()

    def _free(self) -> None:
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()

    def __enter__(self) -> SimWorld:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- queries ----------------------------------------------------------------------------------

    @property
    def robots(self) -> list[str]:
        return [r.name for r in self.scene.robots]

    def robot_model(self, robot: str) -> RobotModel:
        return self.spec.robots[robot]

    def camera_model(self, robot: str) -> CameraModel:
        """The intrinsics of ``robot``'s head camera (what its images are rendered with)."""
        return self.spec.robots[robot].lens

    def joint_angles(self, robot: str, t: float) -> dict[str, float]:
        """Every movable joint's angle at scene time ``t`` (joints without motion are at 0),
        but joints moved by servos (:meth:`follow`) where the servos are now."""
        rm = self.spec.robots[robot]
        moving = rm.robot.angles(t)
        followed = self._followed.get(robot, {})
        return {j: followed.get(j, moving.get(j, 0.0)) for j in rm.tree.movable_joints}

    def joint_readings(self, robot: str, t: float) -> dict[str, float]:
        """What ``robot``'s joint encoders report at scene time ``t``: :meth:`joint_angles`, but
        the joints the scene moves as they were the perturbation's ``delay`` earlier."""
        delay = self.spec.robots[robot].robot.perturb.delay
        if not delay:
            return self.joint_angles(robot, t)
        late = self.joint_angles(robot, t - delay)
        followed = self._followed.get(robot, {})
        return {j: a if j in followed else late[j] for j, a in self.joint_angles(robot, t).items()}

    def body_angles(self, robot: str, t: float) -> dict[str, float]:
        """Where ``robot``'s joints physically stand at scene time ``t``: :meth:`joint_angles`
        less the perturbation's ``joint_zero`` (an encoder reads that much more)."""
        zero = self.spec.robots[robot].robot.perturb.joint_zero
        return {j: a - zero.get(j, 0.0) for j, a in self.joint_angles(robot, t).items()}

    def follow(self, robot: str, angles: Mapping[str, float]) -> None:
        """Put joints of ``robot`` where its servos are (instead of the scene's keyframes)."""
        with self._lock:
            self._followed.setdefault(robot, {}).update(angles)
            self._time = None  # the state at a cached time is no longer the state

    # -- state ------------------------------------------------------------------------------------

    def _set_time(self, t: float) -> None:
        if t == self._time:
            return
        d = self.data
        for name, adr in self._qpos.items():
            for joint, value in self.body_angles(name, t).items():
                d.qpos[adr[joint]] = value
        for obj_id, track in self.tracks.items():
            k = self._mocap[obj_id]
            if track.present(t):
                place = track.placement(t)
                d.mocap_pos[k] = place.p
                mujoco.mju_mat2Quat(d.mocap_quat[k], np.ascontiguousarray(place.R).ravel())
            else:
                d.mocap_pos[k] = _AWAY
        light = self._levels
        if not light.light_constant:
            for k, lamp in enumerate(light.lamps):
                self.model.light_diffuse[k] = self._diffuse[k] * lamp.at(t)
            self.model.vis.headlight.ambient[:] = self._ambient * light.ambient.at(t)
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_camlight(self.model, d)
        self._time = t

    def _draw(self, robot: str, option: mujoco.MjvOption, segmentation: bool) -> np.ndarray:
        """Render ``robot``'s camera in the current state (RGB, or MuJoCo's segmentation).

        An OpenGL context stays bound to the thread that made it current, so every GL call
        (creating, rendering, freeing) runs on one thread of the world's own.
        """

        def draw() -> np.ndarray:
            cam = self.spec.robots[robot].platform.camera
            size = (cam.height, cam.width)
            r = self._renderers.get(size)
            if r is None:
                r = self._renderers[size] = mujoco.Renderer(self.model, *size)
            r.update_scene(self.data, camera=self._camera_id[robot], scene_option=option)
            if not segmentation:
                return r.render()
            r.enable_segmentation_rendering()
            try:
                return r.render()
            finally:
                r.disable_segmentation_rendering()

        if self._gl is None:
            self._gl = ThreadPoolExecutor(max_workers=1, thread_name_prefix="percept-sim-gl")
        return self._gl.submit(draw).result()

    def _camera_world(self, robot: str) -> CameraPose:
        cid = self._camera_id[robot]
        R = self.data.cam_xmat[cid].reshape(3, 3) @ CAMERA_FROM_MJCAM.T
        return CameraPose(R=R.copy(), t=self.data.cam_xpos[cid].copy())

    # -- rendering --------------------------------------------------------------------------------

    def render(self, robot: str, t: float, effects: bool = True) -> np.ndarray:
        """``robot``'s camera image at scene time ``t``: BGR ``uint8`` (height, width, 3), with
        the scene's camera exposure, noise and flicker unless ``effects`` is False."""
        with self._lock:
            shutter = self.scene.camera.shutter
            shift = self._view_shift(robot, t - shutter, t) if effects and shutter else None
            self._set_time(t)
            rgb = self._draw(robot, self._options[robot], segmentation=False)
        image = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        if shift is not None:
            image = motion_blur(image, shift)
        return self._effects(image, robot, t) if effects else image

    def _view_shift(self, robot: str, t0: float, t1: float) -> tuple[float, float]:
        """How far (dx, dy pixels) the scene at the centre of ``robot``'s view moves in the image
        from ``t0`` to ``t1`` as the camera turns (its own travel is negligible against the
        distance of what it sees)."""
        self._set_time(t0)
        before = self._camera_world(robot).R
        self._set_time(t1)
        after = self._camera_world(robot).R
        lens = self.camera_model(robot)
        ahead = before.T @ after[:, 0]  # the centre ray at t1, in the camera at t0
        uv = lens.project(ahead[None, :])[0]
        if not np.isfinite(uv).all():
            return (0.0, 0.0)
        return (float(uv[0] - lens.cx), float(uv[1] - lens.cy))

    def _effects(self, image: np.ndarray, robot: str, t: float) -> np.ndarray:
        fx = self._camera_effects.get(robot)
        if fx is None:
            index = self.robots.index(robot)
            fx = Effects(self.scene.camera, self.scene.seed, index, image.shape)
            self._camera_effects[robot] = fx
        r, g, b = (level.at(t) for level in self._levels.white_balance)
        return fx.apply(image, t, self._levels.exposure.at(t), (r, g, b))

    def labels(self, robot: str, t: float) -> np.ndarray:
        """Segmentation of ``robot``'s camera image at ``t``: per pixel the label of what is seen
        there (an object's id; ``BOX_LABEL + id`` for boxes; ``ROBOT_LABEL + index`` for
        robots; 0 for floor and sky), ``int64`` (height, width)."""
        with self._lock:
            self._set_time(t)
            return self._segment(robot, self._options[robot])

    def _segment(self, robot: str, option: mujoco.MjvOption) -> np.ndarray:
        seg = self._draw(robot, option, segmentation=True)
        ids = np.where(seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), seg[..., 0], -1)
        return self._geom_label[ids + 1]

    def _unoccluded(self, robot: str, obj_id: int) -> tuple[int, BBox | None]:
        """Pixel count and bounding box of object ``obj_id`` rendered with nothing else in the
        scene; remembered while neither the object nor the camera moves."""
        d, cid, k = self.data, self._camera_id[robot], self._mocap[obj_id]
        key = (
            robot,
            obj_id,
            *(
                a.tobytes()
                for a in (d.mocap_pos[k], d.mocap_quat[k], d.cam_xpos[cid], d.cam_xmat[cid])
            ),
        )
        known = self._solo_cache.get(key)
        if known is not None:
            return known
        groups = self.model.geom_group
        geoms = self._object_geoms[obj_id]
        saved = groups[geoms].copy()
        groups[geoms] = SOLO_GROUP
        try:
            mask = self._segment(robot, self._solo) == obj_id
        finally:
            groups[geoms] = saved
        if len(self._solo_cache) >= _SOLO_CACHE:
            self._solo_cache.clear()
        found = self._solo_cache[key] = (int(mask.sum()), _bbox(mask))
        return found

    # -- truth ------------------------------------------------------------------------------------

    def truth(self, t: float, views: Iterable[str] | None = None) -> Truth:
        """The truth at scene time ``t``, with the camera views of ``views`` (default: all)."""
        with self._lock:
            self._set_time(t)
            objects: dict[int, ObjectTruth] = {}
            for obj in self.scene.objects:
                track = self.tracks[obj.id]
                if not track.present(t):
                    continue
                place = track.placement(t)
                objects[obj.id] = ObjectTruth(
                    id=obj.id,
                    name=obj.label,
                    shape=obj.shape,
                    color=obj.color,
                    size=obj.size,
                    position=place.p.copy(),
                    R=place.R.copy(),
                    standing=place.standing,
                    top=float(place.corners(track.size)[:, 2].max()),
                )
            robots: dict[str, RobotTruth] = {}
            for r in self.scene.robots:
                world_cam = self._camera_world(r.name)
                to_robot = invert(ground_transform(*r.pose))
                robots[r.name] = RobotTruth(
                    name=r.name,
                    pose=r.pose,
                    joints=self.joint_angles(r.name, t),
                    camera=CameraPose.from_matrix(to_robot @ world_cam.matrix()),
                    camera_world=world_cam,
                )
            boxes = {b.id: b.pose for b in self.scene.boxes}
            names = self.robots if views is None else list(views)
            seen = {name: self._view(name, objects, robots[name].camera_world, t) for name in names}
            return Truth(t=t, objects=objects, boxes=boxes, robots=robots, views=seen)

    def _view(
        self, robot: str, objects: dict[int, ObjectTruth], camera: CameraPose, t: float
    ) -> View:
        """What ``robot`` sees at scene time ``t``, the time the state was last set to."""
        lens = self.spec.robots[robot].lens
        labels = self._segment(robot, self._options[robot])
        to_camera = invert(camera.matrix())

        def project(points: np.ndarray) -> np.ndarray:
            return lens.project(points @ to_camera[:3, :3].T + to_camera[:3, 3])

        out: dict[int, ObjectView] = {}
        kernel = np.ones((3, 3), np.uint8)
        for obj_id in objects:
            mask = labels == obj_id
            bbox, pixels = _bbox(mask), int(mask.sum())
            corners = self.tracks[obj_id].placement(t).corners(self.tracks[obj_id].size)
            could_show = pixels > 0 or _may_show(project(corners), lens)
            if pixels:
                ring = cv2.dilate(mask.astype(np.uint8), kernel).astype(bool) & ~mask
                neighbours = labels[ring]
                touched = bool(np.any((neighbours != 0) & (neighbours != obj_id)))
            else:
                touched = True
            if could_show and touched:
                total, bbox_full = self._unoccluded(robot, obj_id)
            else:
                total, bbox_full = pixels, bbox
            visible = min(pixels / total, 1.0) if total else 0.0
            out[obj_id] = ObjectView(obj_id, bbox, bbox_full, pixels, visible)
        boxes = {}
        markers: dict[int, MarkerView] = {}
        for box in self.scene.boxes:
            mask = labels == BOX_LABEL + box.id
            boxes[box.id] = (_bbox(mask), int(mask.sum()))
            T_box = ground_transform(*box.pose)
            for m in box.markers:
                T = T_box @ marker_on_box(box.size, m.face, m.offset, m.roll)
                local = np.column_stack([_MARKER_CORNERS * m.side, np.zeros(4)])
                world = local @ T[:3, :3].T + T[:3, 3]
                uv = project(world)
                facing = float(T[:3, 2] @ (camera.t - T[:3, 3])) > 0
                inside = bool(np.all(np.isfinite(uv)) and np.all(lens.contains(uv)))
                markers[m.id] = MarkerView(m.id, box.id, uv, facing, inside)
        robots = {}
        for index, r in enumerate(self.scene.robots):
            if r.name != robot:
                mask = labels == ROBOT_LABEL + index
                robots[r.name] = (_bbox(mask), int(mask.sum()))
        return View(robot=robot, objects=out, boxes=boxes, markers=markers, robots=robots)
