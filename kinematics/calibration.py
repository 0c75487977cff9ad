"""Calibrating the head: the camera's pose on its link, the head joints' zero offsets and the
delay between a frame's stamp and the joint readings, from markers seen at many head poses.

One bundle-style least-squares problem over the marker corners of all frames: a corner's pixel is
predicted by forward kinematics with the joint readings interpolated to the frame's stamp plus the
delay, less each joint's zero offset, the camera moved on its link by the mounting correction,
and the marker where its body (a box or a board on the floor) stands. Bodies whose pose was not
measured are estimated with the rest (on the floor: x, y and heading).

Two parameters are never separable, whatever the sweep, and are handled by convention:

- the zero of the last joint before the camera: turning that joint by a constant is exactly a
  change of the camera's mounting, so it is folded into the mounting (the corrected profile gives
  the same camera pose at every joint angle);
- the zero of the first joint when no body's pose is measured, if its axis is vertical: turning
  it is turning the whole world about the robot. That one is refused: measure one body.

Any other parameter the sweep leaves undetermined (a joint that never moved, a delay with a head
that never moved while frames were taken) is found from the Jacobian and refused by name.

Conventions are those of the simulated world's perturbation: a joint reads ``zero`` more than it
stands at; the joint readings at ``stamp + delay`` belong to a frame stamped ``stamp``; the camera
sits at ``profile camera @ transform(offset, rotation)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from percept.kinematics.camera import CameraModel
from percept.kinematics.least_squares import levenberg_marquardt, row_by_row
from percept.kinematics.pose import axis_angle_matrix, matrix_rpy, transform
from percept.kinematics.tree import KinematicTree

DELAY_RANGE = 0.25
"""Seconds either way the delay is looked for in."""
LEAST_FRAMES = 10
"""Frames with markers below which nothing is estimated."""
_UNDETERMINED = 1e-5  # a parameter whose Jacobian column is this much its own: undetermined
_DELAY_STEP = 0.005  # seconds between the delays tried before the joint solve
_HUBER_PX = 2.0  # corner errors beyond this many pixels count linearly: a misread one weighs less


class CalibrationRefused(ValueError):
    """The data cannot determine the calibration; the message says what is missing or which
    parameter is undetermined (``parameters``)."""

    def __init__(self, problem: str, parameters: Sequence[str] = ()) -> None:
        super().__init__(problem)
        self.parameters = tuple(parameters)


@dataclass(frozen=True)
class MarkerOnBody:
    """A marker's corners (4, 3) in the frame of the body it is fixed to (cv2.aruco's order)."""

    id: int
    body: int
    corners: np.ndarray


@dataclass(frozen=True)
class Sighting:
    """A marker's corners (4, 2) found in the frame stamped ``t`` (seconds)."""

    t: float
    marker: int
    corners: np.ndarray


@dataclass(frozen=True)
class Readings:
    """Joint readings over time: ``t`` (N,) increasing, ``angles`` joint name -> (N,) radians."""

    t: np.ndarray
    angles: dict[str, np.ndarray]

    def at(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """Each joint's reading interpolated to times ``t``."""
        return {n: np.interp(t, self.t, a) for n, a in self.angles.items()}


@dataclass(frozen=True)
class Estimate:
    """One estimated number and its standard deviation (from the Jacobian)."""

    value: float
    sigma: float


@dataclass(frozen=True)
class HeadCalibration:
    """What :func:`calibrate_head` found, in the perturbation's units (metres, radians,
    seconds); ``bodies`` are the floor poses (x, y, heading) of every body, measured or found."""

    camera_offset: tuple[Estimate, Estimate, Estimate]
    camera_rotation: tuple[Estimate, Estimate, Estimate]
    joint_zero: dict[str, Estimate]
    delay: Estimate
    folded: tuple[str, ...]
    bodies: dict[int, tuple[float, float, float]]
    reprojection_px_before: float
    reprojection_px_after: float
    frames: int
    sightings: int

    def mounting(self) -> np.ndarray:
        """The 4x4 transform profile camera <- camera."""
        return transform(
            [e.value for e in self.camera_offset], [e.value for e in self.camera_rotation]
        )


@dataclass
class _Problem:
    """The parameter vector's layout and the data, for the residuals."""

    tree: KinematicTree
    lens: CameraModel
    readings: Readings
    stamps: np.ndarray  # (F,) frame stamps
    frame_of: np.ndarray  # (S,) frame index of each sighting
    body_of: np.ndarray  # (S,) body index of each sighting
    corners: np.ndarray  # (S, 4, 3) corners in their body's frame
    seen: np.ndarray  # (S, 4, 2) pixels
    zeros: list[str]
    fixed: dict[int, np.ndarray]  # body index -> 4x4 ground <- body
    free: list[int]  # body indices estimated
    names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.names = [f"camera_offset.{a}" for a in "xyz"]
        self.names += [f"camera_rotation.{a}" for a in ("roll", "pitch", "yaw")]
        self.names += [f"joint_zero.{n}" for n in self.zeros]
        self.names.append("delay")
        for b in self.free:
            self.names += [f"body[{b}].{a}" for a in ("x", "y", "heading")]

    def split(self, p: np.ndarray) -> tuple[np.ndarray, dict[str, float], float, list[np.ndarray]]:
        k = 6 + len(self.zeros)
        mount = transform(p[0:3].tolist(), p[3:6].tolist())
        zeros = {n: float(v) for n, v in zip(self.zeros, p[6:k], strict=True)}
        bodies = dict(self.fixed)
        for i, b in enumerate(self.free):
            x, y, heading = p[k + 1 + 3 * i : k + 4 + 3 * i]
            bodies[b] = transform((x, y, 0.0), (0.0, 0.0, heading))
        return mount, zeros, float(p[k]), [bodies[b] for b in range(len(bodies))]

    def poses(self, p: np.ndarray) -> np.ndarray:
        """(F, 4, 4) camera <- ground of every frame."""
        mount, zeros, delay, _ = self.split(p)
        angles = self.readings.at(self.stamps + delay)
        T = self.tree.camera_matrices({n: a - zeros.get(n, 0.0) for n, a in angles.items()})
        return _inverse(T @ mount)

    def residuals(self, p: np.ndarray) -> np.ndarray:
        _, _, _, bodies = self.split(p)
        to_camera = self.poses(p)[self.frame_of]  # (S, 4, 4)
        placed = np.stack(bodies)[self.body_of]  # (S, 4, 4) ground <- body
        T = to_camera @ placed
        points = np.einsum("sij,skj->ski", T[:, :3, :3], self.corners) + T[:, None, :3, 3]
        uv = self.lens.project(points.reshape(-1, 3)).reshape(-1, 4, 2)
        # A corner behind the camera (a wild guess) counts as far off, not as NaN.
        return np.nan_to_num(uv - self.seen, nan=1e3).ravel()


def _inverse(T: np.ndarray) -> np.ndarray:
    """The inverses of rigid transforms (n, 4, 4)."""
    Rt = np.swapaxes(T[:, :3, :3], 1, 2)
    out = np.zeros_like(T)
    out[:, :3, :3] = Rt
    out[:, :3, 3] = -np.einsum("nij,nj->ni", Rt, T[:, :3, 3])
    out[:, 3, 3] = 1.0
    return out


def calibrate_head(
    tree: KinematicTree,
    lens: CameraModel,
    sightings: Sequence[Sighting],
    readings: Readings,
    markers: Mapping[int, MarkerOnBody],
    measured: Mapping[int, np.ndarray],
) -> HeadCalibration:
    """Estimate the head calibration from marker ``sightings`` and joint ``readings``.

    ``markers`` places each marker id on a body; ``measured`` gives the 4x4 pose ground <- body of
    the bodies whose pose is known; the others stand on the floor, where the profile as it is
    sees them first. Raises :class:`CalibrationRefused` naming what is missing or undetermined.
    """
    problem = _problem(tree, lens, sightings, readings, markers, measured)
    bodies = sorted({m.body for m in markers.values()})
    k = 6 + len(problem.zeros)
    p0 = np.zeros(k + 1 + 3 * len(problem.free))
    for i, b in enumerate(problem.free):
        p0[k + 1 + 3 * i : k + 4 + 3 * i] = _guess_body(problem, p0, b)
    # The delay first, on its own: where the image motion and the joint motion agree best.
    delays = np.round(np.arange(-DELAY_RANGE, DELAY_RANGE + 1e-9, _DELAY_STEP), 9)
    costs = []
    for d in delays:
        p0[k] = d
        costs.append(_rms(problem.residuals(p0)))
    p0[k] = float(delays[int(np.argmin(costs))])
    _check_determined(problem, _jacobian(problem, p0))
    lo = np.full(p0.size, -np.inf)
    hi = np.full(p0.size, np.inf)
    lo[k], hi[k] = -DELAY_RANGE, DELAY_RANGE
    x, _ = levenberg_marquardt(
        row_by_row(problem.residuals), p0, lower=lo, upper=hi, huber=_HUBER_PX
    )
    J = _jacobian(problem, x)
    _check_determined(problem, J)
    r = problem.residuals(x)
    dof = max(r.size - x.size, 1)
    cov = np.linalg.pinv(J.T @ J) * float(r @ r) / dof
    sigma = np.sqrt(np.clip(np.diag(cov), 0.0, None))

    def est(i: int) -> Estimate:
        return Estimate(float(x[i]), float(sigma[i]))

    _, _, _, placed = problem.split(x)
    before = np.zeros_like(x)
    before[k + 1 :] = x[k + 1 :]  # the bodies where they are found: the profile's own error
    return HeadCalibration(
        camera_offset=(est(0), est(1), est(2)),
        camera_rotation=(est(3), est(4), est(5)),
        joint_zero={n: est(6 + i) for i, n in enumerate(problem.zeros)},
        delay=est(k),
        folded=tuple(n for n in _chain_joints(tree, readings) if n not in problem.zeros),
        bodies={
            bodies[i]: (float(T[0, 3]), float(T[1, 3]), math.atan2(T[1, 0], T[0, 0]))
            for i, T in enumerate(placed)
        },
        reprojection_px_before=_reprojection(problem, _best_bodies(problem, before)),
        reprojection_px_after=_reprojection(problem, x),
        frames=len(problem.stamps),
        sightings=len(problem.frame_of),
    )


def _guess_body(problem: _Problem, p: np.ndarray, body: int) -> tuple[float, float, float]:
    """Where body ``body`` stands by the profile as it is: its first sighting's centre ray meets
    the height of that marker's centre; the heading of twelve that reprojects best."""
    first = int(np.flatnonzero(problem.body_of == body)[0])
    T = np.linalg.inv(problem.poses(p)[problem.frame_of[first]])  # ground <- camera
    centre = problem.corners[first].mean(axis=0)  # in the body frame
    ray = T[:3, :3] @ problem.lens.pixel_rays(problem.seen[first].mean(axis=0, keepdims=True))[0]
    a = (centre[2] - T[2, 3]) / ray[2] if abs(ray[2]) > 1e-9 else 1.0
    seen = T[:3, 3] + max(a, 0.05) * ray
    best: tuple[float, tuple[float, float, float]] | None = None
    for heading in np.linspace(-math.pi, math.pi, 12, endpoint=False):
        c, s = math.cos(heading), math.sin(heading)
        x = float(seen[0] - (c * centre[0] - s * centre[1]))
        y = float(seen[1] - (s * centre[0] + c * centre[1]))
        placed = transform((x, y, 0.0), (0.0, 0.0, heading))
        points = problem.corners[first] @ placed[:3, :3].T + placed[:3, 3]
        to_camera = np.linalg.inv(T)
        uv = problem.lens.project(points @ to_camera[:3, :3].T + to_camera[:3, 3])
        error = float(np.nan_to_num(np.abs(uv - problem.seen[first]), nan=1e6).sum())
        if best is None or error < best[0]:
            best = (error, (x, y, float(heading)))
    assert best is not None
    return best[1]


def _chain_joints(tree: KinematicTree, readings: Readings) -> list[str]:
    """The joints between the ground and the camera that have readings, in chain order."""
    return [n for n in tree.camera_joints if n in readings.angles]


def _problem(
    tree: KinematicTree,
    lens: CameraModel,
    sightings: Sequence[Sighting],
    readings: Readings,
    markers: Mapping[int, MarkerOnBody],
    measured: Mapping[int, np.ndarray],
) -> _Problem:
    """The problem's layout, after checking there is enough to solve it."""
    chain = _chain_joints(tree, readings)
    if not chain:
        raise CalibrationRefused("no joint readings of the joints between ground and camera")
    used = [s for s in sightings if s.marker in markers]
    stamps = np.array(sorted({s.t for s in used}))
    if len(stamps) < LEAST_FRAMES:
        raise CalibrationRefused(
            f"too few markers seen: markers in {len(stamps)} frames, at least {LEAST_FRAMES} "
            "needed (put the boxes or the board where the sweep sees them)",
            ["markers"],
        )
    if len(readings.t) < 2 or stamps[0] < readings.t[0] or stamps[-1] > readings.t[-1]:
        raise CalibrationRefused("the joint readings do not cover the frames' times", ["delay"])
    bodies = sorted({m.body for m in markers.values()})
    index = {b: i for i, b in enumerate(bodies)}
    # The last joint's zero is the camera's mounting turned about that joint's axis.
    zeros = chain[:-1]
    fixed = {index[b]: np.asarray(T, dtype=float) for b, T in measured.items() if b in index}
    if not fixed and zeros and _vertical_first(tree, zeros[0]):
        raise CalibrationRefused(
            f"joint_zero.{zeros[0]} is undetermined: with no body's pose measured, turning "
            f"{zeros[0]} is turning the whole world about the robot; measure one box's or the "
            "board's pose on the floor",
            [f"joint_zero.{zeros[0]}"],
        )
    return _Problem(
        tree=tree,
        lens=lens,
        readings=readings,
        stamps=stamps,
        frame_of=np.searchsorted(stamps, [s.t for s in used]),
        body_of=np.array([index[markers[s.marker].body] for s in used]),
        corners=np.stack([markers[s.marker].corners for s in used]).astype(float),
        seen=np.stack([s.corners for s in used]).astype(float),
        zeros=zeros,
        fixed=fixed,
        free=[i for i in range(len(bodies)) if i not in fixed],
    )


def _vertical_first(tree: KinematicTree, joint: str) -> bool:
    """Whether ``joint``'s axis is vertical in the ground frame at zero angles."""
    spec = next(j for j in tree.joints if j.name == joint)
    T = tree.link_transform(spec.child, {})
    axis = T[:3, :3] @ np.asarray(spec.axis, dtype=float)
    return abs(abs(axis[2]) / float(np.linalg.norm(axis)) - 1.0) < 1e-6


def _jacobian(problem: _Problem, p: np.ndarray) -> np.ndarray:
    """Central differences; the delay's step spans more than a reading's interval would not."""
    steps = np.full(p.size, 1e-6)
    steps[6 + len(problem.zeros)] = 1e-4
    J = np.empty((problem.residuals(p).size, p.size))
    for i, h in enumerate(steps):
        up, down = p.copy(), p.copy()
        up[i] += h
        down[i] -= h
        J[:, i] = (problem.residuals(up) - problem.residuals(down)) / (2 * h)
    return J


def _check_determined(problem: _Problem, J: np.ndarray) -> None:
    """Refuse, by name, the parameters the data leaves undetermined: those whose Jacobian column
    is (nearly) zero, and those that take part in a combination of columns that (nearly) cancels
    (a change of them that moves no corner)."""
    norms = np.linalg.norm(J, axis=0)
    dead = norms < 1e-9 * max(float(norms.max()), 1e-12)
    Jn = J / np.where(dead, 1.0, norms)
    _, sv, Vt = np.linalg.svd(Jn[:, ~dead], full_matrices=False)
    weak = np.zeros(J.shape[1], dtype=bool)
    for v in Vt[sv < _UNDETERMINED * sv[0]]:
        weak[np.flatnonzero(~dead)[np.abs(v) > 0.1]] = True
    bad = [n for n, d, w in zip(problem.names, dead, weak, strict=True) if d or w]
    if bad:
        raise CalibrationRefused(
            f"the sweep leaves {', '.join(bad)} undetermined: sweep every head joint over its "
            "range, moving while frames are taken, with markers in view",
            bad,
        )


def _rms(r: np.ndarray) -> float:
    """Root mean square corner error in pixels of residuals (x, y per corner)."""
    return float(np.sqrt(np.mean(r.reshape(-1, 2) ** 2, axis=0).sum()))


def _reprojection(problem: _Problem, p: np.ndarray) -> float:
    """Median corner error in pixels."""
    r = problem.residuals(p).reshape(-1, 2)
    return float(np.median(np.linalg.norm(r, axis=1)))


def _best_bodies(problem: _Problem, p: np.ndarray) -> np.ndarray:
    """``p`` with the free bodies fitted for the profile as it is (no other correction): the
    reprojection error the uncorrected profile leaves at best."""
    k = 7 + len(problem.zeros)
    if not problem.free:
        return p

    def residuals(bodies: np.ndarray) -> np.ndarray:
        return problem.residuals(np.concatenate([p[:k], bodies]))

    bodies, _ = levenberg_marquardt(row_by_row(residuals), p[k:], huber=_HUBER_PX)
    return np.concatenate([p[:k], bodies])


def corrected_origin(tree: KinematicTree, joint: str, zero: float) -> np.ndarray:
    """The 4x4 origin of revolute ``joint`` that makes the readings of a joint that reads
    ``zero`` more than it stands at give the true pose: ``origin @ rotation(axis, -zero)``."""
    spec = next(j for j in tree.joints if j.name == joint)
    T = transform(spec.xyz, spec.rpy)
    T[:3, :3] = T[:3, :3] @ axis_angle_matrix(_unit(spec.axis), -zero)
    return T


def corrected_mount(tree: KinematicTree, mounting: np.ndarray) -> tuple[str, np.ndarray]:
    """The fixed joint that carries the camera link and its corrected 4x4 origin for the camera
    moved by ``mounting`` (profile camera <- camera): ``origin @ C @ mounting @ C^-1`` with
    ``C`` the profile's ``camera_rpy`` turn. Refused when the camera link moves with a joint."""
    camera_link = tree.settings.camera_link
    spec = next((j for j in tree.joints if j.child == camera_link), None)
    if spec is None or spec.type != "fixed":
        raise CalibrationRefused(
            f"the camera link {camera_link!r} is not carried by a fixed joint: give it one "
            "(e.g. camera_mount) so that its mounting can be corrected"
        )
    C = transform((0.0, 0.0, 0.0), tree.settings.camera_rpy)
    return spec.name, transform(spec.xyz, spec.rpy) @ C @ mounting @ np.linalg.inv(C)


def xyz_rpy(T: np.ndarray) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Translation and URDF roll, pitch, yaw of a 4x4 transform."""
    x, y, z = (float(v) for v in T[:3, 3])
    return (x, y, z), matrix_rpy(T[:3, :3])


def _unit(v: Sequence[float]) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    return a / float(np.linalg.norm(a))
