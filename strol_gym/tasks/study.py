"""The user study's Tasks (paper, "User Study"): a Panda carries a cup past a pitcher to a plate.

Task frame = the robot base frame: metres, x forward, y left, z up from the table top (the base
stands on the table). The state is the cup's pose: position (Task 1, 3-D) or position and
orientation (Tasks 2-3, 6-D: roll, pitch, yaw of the cup frame, R = Rz(yaw) Ry(pitch) Rx(roll);
the cup is upright when roll = pitch = 0). Corrections are pose changes of the same size
(3-D for Task 1, 6-D for Tasks 2-3). Features (all 0 at best, negative otherwise):

- ``pitcher``: −‖x_xy − pitcher_xy‖ (a negative weight keeps the cup away from the pitcher);
- ``plate``: −‖x − plate‖ (a positive weight carries it to the plate);
- ``table``: −z (a positive weight keeps it low, close to the table);
- ``upright`` (Tasks 2-3): −tilt, the angle in rad between the cup's axis and the vertical.

θ* per Task is the issue's table (Task 3's lies outside the prior). The prior is the designer's
multimodal prior (docs/study.md): 3 modes for Task 1 (θ*_1 among them), 4 for Tasks 2-3 (θ*_2
and Task 1's preference among them), none near θ*_3.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np

from strol_gym import checks
from strol_gym.compiled import use_fast
from strol_gym.planning import plan_linear_reward
from strol_gym.priors import MixturePrior, Prior
from strol_gym.tasks.base import Task

PITCHER = np.array([0.35, 0.10, 0.0])
PLATE = np.array([0.70, -0.45, 0.10])
HOME_Q_TASK1 = np.array([0.8385, -0.0609, 0.2447, -1.5657, 0.0089, 1.5335, 1.8607])
HOME_Q_TASK2 = np.array([1.13894, -0.129095, -0.236155, -1.73935, 0.566207, 2.39615, 1.49282])
"""Home joints as the paper's robot reports them (real Panda convention); the MuJoCo model's
joint 6 is offset by −π/2 (strol_gym.envs.panda), which the env applies."""

THETA_STAR = {
    1: np.array([-1.5, 0.8, 0.8]),
    2: np.array([-0.8, 0.8, 0.8, 0.8]),
    3: np.array([-0.8, -0.8, -0.8, 0.8]),
}
MODES_3 = np.array([[-1.5, 0.8, 0.8], [0.8, -0.8, 0.8], [-0.8, 0.8, -0.8]])
"""Task 1's prior modes: θ*_1 (avoid the pitcher, reach the plate, stay low), "near the pitcher,
away from the plate, low" and "away from the pitcher, to the plate, high"."""
MODES_4 = np.array(
    [[-0.8, 0.8, 0.8, 0.8], [-1.5, 0.8, 0.8, 0.0], [0.8, -0.8, 0.8, -0.8], [0.8, 0.8, -0.8, 0.0]]
)
"""Tasks 2-3's prior modes: θ*_2, Task 1's preference (orientation indifferent), and two
others; the nearest to θ*_3 is 2.3 away (jitter 0.1), so Task 3 is outside the prior."""

CONTROL_DT = 0.05
"""The env's control step (s)."""
SEGMENT_TIME = 0.5
"""Seconds the robot takes per plan waypoint (≤ 0.05 m apart: ≤ 0.1 m/s)."""

POS_LOW = np.array([0.20, -0.60, 0.05])
POS_HIGH = np.array([0.80, 0.60, 0.70])
"""Where the planner may put the cup (m): reachable by the arm, above the table."""
ANG_LIMIT = 1.3
"""|roll|, |pitch| the planner may use (rad); yaw is not planned (no feature depends on it)."""

# Home cup poses (FK of the home joints in strol_gym.envs.study.scene; a test checks them).
START_TASK1 = np.array([0.2473, 0.4760, 0.5026])
START_TASK2 = np.array([0.3772, 0.5631, 0.6193, 0.1258, 0.9303, -1.5862])


def rpy_to_mat(rpy: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), batched: (..., 3) -> (..., 3, 3)."""
    rpy = np.asarray(rpy, dtype=np.float64)
    if rpy.shape == (3,):  # the env's per-step call: plain floats are ~10x faster
        return _rpy_to_mat1(*rpy.tolist())
    r, p, y = np.moveaxis(rpy, -1, 0)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def _rpy_to_mat1(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return np.array(  # flat, then reshaped: numpy reads nested lists more slowly
        (
            *(cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            *(sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            *(-sp, cp * sr, cp * cr),
        )
    ).reshape(3, 3)


def mat_to_rpy(mat: np.ndarray) -> np.ndarray:
    """The inverse of ``rpy_to_mat`` (pitch in [−π/2, π/2]): (..., 3, 3) -> (..., 3)."""
    m = np.asarray(mat, dtype=np.float64)
    if m.shape == (3, 3):  # the env's per-step call
        (r00, _, _), (r10, _, _), (r20, r21, r22) = m.tolist()
        return np.array(
            [
                math.atan2(r21, r22),
                math.asin(min(1.0, max(-1.0, -r20))),
                math.atan2(r10, r00),
            ]
        )
    pitch = np.arcsin(np.clip(-m[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(m[..., 2, 1], m[..., 2, 2])
    yaw = np.arctan2(m[..., 1, 0], m[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles to [−π, π)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


STUDY_ENV = "StROL-Study"
"""The study env's name; version N registers as ``StROL-Study-vN``."""


def study_env_id(version: int) -> str:
    """The env id of study version ``version`` (``StROL-Study-v2``)."""
    return f"{STUDY_ENV}-v{version}"


def _later(version: int) -> str:
    """The suffix a version after v0 adds to a study Task's names ("" for v0, "-v2" for v2)."""
    return f"-v{version}" if version else ""


def study_task_id(version: int, number: int) -> str:
    """A study Task's ``task_id``, the key its shipped ĝ's sidecars record
    (``StROL-Study-v1-task2``)."""
    return f"{study_env_id(version)}-task{number}"


def study_task_name(version: int, number: int) -> str:
    """A study Task's name in the Task registry (``study-task2``, ``study-task2-v1``)."""
    return f"study-task{number}{_later(version)}"


def study_weights_stem(version: int, number: int) -> str:
    """The stem of a study Task's shipped ĝ files, ``<stem>_<kind>.safetensors`` and its
    sidecar ``<stem>_<kind>.json`` (``study2``, ``study2-v1``)."""
    return f"study{number}{_later(version)}"


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask(Task):
    """Shared by the three study Tasks; subclasses fix the study Task number and the version
    (``task_id`` follows from both)."""

    task_id: ClassVar[str] = study_task_id(0, 1)
    weights_stem: ClassVar[str | None] = study_weights_stem(0, 1)
    version: ClassVar[int] = 0
    number: ClassVar[int] = 1
    feature_high: ClassVar[float] = 0.0
    strol_lambda: ClassVar[float] = 1.0
    """StROL's λ in the paper's study (``make_learner("strol", task=...)`` uses it)."""

    prior: Prior = dataclasses.field(default_factory=lambda: MixturePrior(MODES_3, jitter=0.1))
    alpha: float = 2.0
    pitcher: np.ndarray = dataclasses.field(default_factory=PITCHER.copy)
    plate: np.ndarray = dataclasses.field(default_factory=PLATE.copy)
    pos_step: float = 0.1
    """a_max of a correction's position change per axis (m)."""
    ang_step: float = 0.3
    """a_max of a correction's orientation change per axis (rad)."""
    plan_steps: int = 20
    plan_pos_bound: float = 0.05
    plan_ang_bound: float = 0.1

    # ------------------------------------------------------------------ identity
    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Its ``task_id`` (its ĝ's key) and ``weights_stem`` follow from its ``version`` and
        ``number``, unless it sets its own (a Task of another setting built on a study one)."""
        super().__init_subclass__(**kwargs)
        if "task_id" in vars(cls):
            cls.weights_stem = vars(cls).get("weights_stem")  # its own, or its registry name
            return
        cls.task_id = study_task_id(cls.version, cls.number)
        cls.weights_stem = vars(cls).get("weights_stem") or study_weights_stem(
            cls.version, cls.number
        )

    @property
    def theta_star(self) -> np.ndarray:
        """The study participant's θ* for this Task (the issue's table)."""
        return THETA_STAR[self.number].copy()

    @property
    def home_q(self) -> np.ndarray:
        """Home joints in the paper's (real Panda) convention."""
        return (HOME_Q_TASK1 if self.number == 1 else HOME_Q_TASK2).copy()

    @property
    def oriented(self) -> bool:
        """Whether the state and corrections include the cup's orientation (Tasks 2-3)."""
        return self.state_dim == 6

    @property
    def prior_modes(self) -> np.ndarray:
        return MODES_3 if self.dim == 3 else MODES_4

    @property
    def action_bound(self) -> np.ndarray:
        return np.array([self.pos_step] * 3 + [self.ang_step] * (self.action_dim - 3))

    @property
    def robot_action_bound(self) -> np.ndarray:
        """The env's action is a residual setpoint velocity: 0.1 m/s, 0.2 rad/s at |a| = 1,
        applied per 0.05 s control step."""
        per_step = CONTROL_DT / SEGMENT_TIME
        return np.array(
            [self.plan_pos_bound * per_step] * 3
            + [self.plan_ang_bound * per_step] * (self.action_dim - 3)
        )

    def robot_policy(self, x: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
        """u_R per control step: the plan's first step, spread over its ``SEGMENT_TIME``."""
        x, theta_hat = np.atleast_2d(x), np.atleast_2d(theta_hat)
        step = self.plan(theta_hat, x)[:, 1] - x
        if self.oriented:
            step[:, 3:] = wrap_angle(step[:, 3:])
        return step * (CONTROL_DT / SEGMENT_TIME)

    @property
    def feature_scale(self) -> np.ndarray:
        # Distances (m) over a ~1 m workspace and a tilt (rad) up to ~1.3: comparable ranges.
        return np.ones(self.dim)

    @property
    def low(self) -> np.ndarray:
        """The planning box's lower corner (yaw unbounded)."""
        ang = [-ANG_LIMIT, -ANG_LIMIT, -np.inf][: self.state_dim - 3]
        return np.concatenate([POS_LOW, ang])

    @property
    def high(self) -> np.ndarray:
        ang = [ANG_LIMIT, ANG_LIMIT, np.inf][: self.state_dim - 3]
        return np.concatenate([POS_HIGH, ang])

    @property
    def start(self) -> np.ndarray:
        """The cup's pose at the home joints (FK; see the constants above)."""
        return (START_TASK1 if self.number == 1 else START_TASK2).copy()

    # ------------------------------------------------------------------ φ and ∂φ/∂x
    def features(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if x.ndim == 1:  # the env's per-step call: plain floats are ~10x faster
            return self._features1(x)
        dxy = x[..., :2] - self.pitcher[:2]
        dp = x[..., :3] - self.plate
        cols = [
            -np.sqrt(np.einsum("...i,...i->...", dxy, dxy)),
            -np.sqrt(np.einsum("...i,...i->...", dp, dp)),
            -x[..., 2],
        ]
        if self.oriented:
            c = np.cos(x[..., 3]) * np.cos(x[..., 4])
            cols.append(-np.arccos(np.clip(c, -1.0, 1.0)))
        return np.stack(cols, axis=-1)

    def _features1(self, x: np.ndarray) -> np.ndarray:
        """``features`` for one state (the same formulas as the batched path)."""
        px, py, pz, *angles = x.tolist()
        (qx, qy, _), (lx, ly, lz) = self._objects
        out = [
            -math.hypot(px - qx, py - qy),
            -math.sqrt((px - lx) ** 2 + (py - ly) ** 2 + (pz - lz) ** 2),
            -pz,
        ]
        if self.oriented:
            c = math.cos(angles[0]) * math.cos(angles[1])
            out.append(-math.acos(min(1.0, max(-1.0, c))))
        return np.array(out)

    @functools.cached_property
    def _objects(self) -> tuple[list[float], list[float]]:
        """The pitcher and the plate as plain floats, for ``_features1``."""
        return self.pitcher.tolist(), self.plate.tolist()

    def feature_jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂φ/∂x, (..., s) -> (..., d, s) (0 at the kinks)."""
        x = np.asarray(x, dtype=np.float64)
        jac = np.zeros((*x.shape[:-1], self.dim, self.state_dim))
        dxy = x[..., :2] - self.pitcher[:2]
        n = np.sqrt(np.einsum("...i,...i->...", dxy, dxy))[..., None]
        jac[..., 0, :2] = -dxy / np.maximum(n, 1e-12)
        dp = x[..., :3] - self.plate
        n = np.sqrt(np.einsum("...i,...i->...", dp, dp))[..., None]
        jac[..., 1, :3] = -dp / np.maximum(n, 1e-12)
        jac[..., 2, 2] = -1.0
        if self.oriented:
            r, p = x[..., 3], x[..., 4]
            c = np.clip(np.cos(r) * np.cos(p), -1.0, 1.0)
            s = np.sqrt(np.maximum(1.0 - c * c, 1e-12))
            # d(−arccos c) = dc / sqrt(1 − c²)
            jac[..., 3, 3] = -np.sin(r) * np.cos(p) / s
            jac[..., 3, 4] = -np.cos(r) * np.sin(p) / s
        return jac

    # ------------------------------------------------------------------ f, starts, planning
    def dynamics(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """x' = x + u_R + u_H, positions clipped to the planning box, angles wrapped."""
        y = np.asarray(x, dtype=np.float64) + u_r + u_h
        pos = np.minimum(np.maximum(y[..., :3], POS_LOW), POS_HIGH)
        if not self.oriented:
            return pos
        return np.concatenate([pos, wrap_angle(y[..., 3:])], axis=-1)

    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Poses where a correction can begin: uniform in the planning box (yaw uniform in
        [−π, π)). Training draws its states here; the env itself starts at ``start`` (home)."""
        pos = rng.uniform(POS_LOW, POS_HIGH, size=(n, 3))
        if not self.oriented:
            return pos
        ang = rng.uniform([-ANG_LIMIT, -ANG_LIMIT, -np.pi], [ANG_LIMIT, ANG_LIMIT, np.pi], (n, 3))
        return np.concatenate([pos, ang], axis=1)

    @functools.cached_property
    def _plan_scale(self) -> np.ndarray:
        """Planned axes (position, and roll/pitch for Tasks 2-3) scaled so that one step bound
        (``plan_pos_bound``) also bounds the angles by ``plan_ang_bound``."""
        ang = self.plan_ang_bound / self.plan_pos_bound
        return np.array([1.0, 1.0, 1.0] + ([ang, ang] if self.oriented else []))

    @property
    def _plan_axes(self) -> int:
        return 5 if self.oriented else 3

    def plan(self, theta: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Plans maximising Σ_{t=1..T} θ·φ(x_t): (B, d), (B, s) -> (B, T+1, s), T = plan_steps.

        Steps ≤ 0.05 m and ≤ 0.1 rad per axis (paper); yaw is held at x0's (no feature uses it).
        Deterministic (strol_gym.planning).
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=np.float64))
        x0 = np.atleast_2d(np.asarray(x0, dtype=np.float64))
        k, scale = self._plan_axes, self._plan_scale
        tail = x0[:, k:]

        def full(y: np.ndarray) -> np.ndarray:
            y = y * scale
            if tail.shape[1] == 0:
                return y
            return np.concatenate([y, np.zeros((*y.shape[:-1], tail.shape[1]))], axis=-1)

        def feats(y: np.ndarray) -> np.ndarray:
            return self.features(full(y))

        def jac(y: np.ndarray) -> np.ndarray:
            return self.feature_jacobian(full(y))[..., :k] * scale

        low, high = self.low[:k] / scale, self.high[:k] / scale
        targets = self._plan_targets / scale
        plans = plan_linear_reward(
            feats,
            jac,
            theta,
            x0[:, :k] / scale,
            steps=self.plan_steps,
            step_bound=self.plan_pos_bound,
            low=low,
            high=high,
            targets=targets,
            away=False,
            n_random=8,
            n_iters=60,
            keep=4,
            walk=self._plan_walk(x0),
        )
        plans = plans * scale
        if tail.shape[1]:
            plans = np.concatenate(
                [plans, np.broadcast_to(tail[:, None, :], (*plans.shape[:2], tail.shape[1]))],
                axis=-1,
            )
        return plans

    def _plan_walk(self, x0: np.ndarray) -> Callable[[np.ndarray, float], None] | None:
        """A constraint beyond the box for the planner (``planning.WalkFn``); v0-v1: none."""
        return None

    @functools.cached_property
    def _plan_targets(self) -> np.ndarray:
        """Straight-line starts: the plate, above the plate, the box's corners, all upright."""
        lo, hi = POS_LOW, POS_HIGH
        corners = np.array([[(lo, hi)[(i >> k) & 1][k] for k in range(3)] for i in range(8)])
        pts = np.vstack([self.plate, [*self.plate[:2], hi[2]], corners])
        if self.oriented:
            pts = np.hstack([pts, np.zeros((len(pts), 2))])
        return pts


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask1(StudyTask):
    """Study Task 1: carry the cup to the plate, close to the table, away from the pitcher."""

    number: ClassVar[int] = 1
    strol_lambda: ClassVar[float] = 0.25
    feature_names: ClassVar[tuple[str, ...]] = ("pitcher", "plate", "table")
    state_dim: ClassVar[int] = 3
    action_dim: ClassVar[int] = 3


def _prior4() -> Prior:
    return MixturePrior(MODES_4, jitter=0.1)


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask2(StudyTask):
    """Study Task 2: as Task 1, and keep the cup upright (6-D pose corrections)."""

    number: ClassVar[int] = 2
    feature_names: ClassVar[tuple[str, ...]] = ("pitcher", "plate", "table", "upright")
    state_dim: ClassVar[int] = 6
    action_dim: ClassVar[int] = 6
    prior: Prior = dataclasses.field(default_factory=_prior4)


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask3(StudyTask2):
    """Study Task 3: away from every object, cup upright; θ* outside the prior."""

    number: ClassVar[int] = 3


STUDY_TASKS: dict[int, type[StudyTask]] = {1: StudyTask1, 2: StudyTask2, 3: StudyTask3}


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask1V1(StudyTask1):
    """Task 1 as StROL-Study-v1's study runs it: the same Task; its own id, so that the ĝ
    trained for v1's corrections (``pretrained/study1-v1_*``) are found for it and v0's
    published ĝ for v0."""

    version: ClassVar[int] = 1


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask2V1(StudyTask2):
    """Task 2 for StROL-Study-v1's ĝ (see ``StudyTask1V1``)."""

    version: ClassVar[int] = 1


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask3V1(StudyTask3):
    """Task 3 for StROL-Study-v1's ĝ (see ``StudyTask1V1``)."""

    version: ClassVar[int] = 1


STUDY_TASKS_V1: dict[int, type[StudyTask]] = {1: StudyTask1V1, 2: StudyTask2V1, 3: StudyTask3V1}


# ---------------------------------------------------------------------- StROL-Study-v2's Tasks
CUP_CLEARANCE = 0.08
"""m kept between the cup's centre (the state) and an object: the cup's bounding sphere
(r 4 cm, 10 cm tall: 0.064 m) and 1.6 cm to spare."""
KEEP_OUT = np.array(
    [
        [PITCHER[0], PITCHER[1], 0.07 + CUP_CLEARANCE, 0.24 + CUP_CLEARANCE],
        [PLATE[0], PLATE[1], 0.115 + CUP_CLEARANCE, 0.105 + CUP_CLEARANCE],
    ]
)
"""The objects' hulls the cup's centre stays out of, already widened by ``CUP_CLEARANCE``:
vertical cylinders standing on the table, rows (x, y, radius, top) in m. The pitcher (r 7 cm,
24 cm tall); the plate (r 10 cm, its top 10.5 cm up) on its riser (a 16 cm square, whose
corners reach 11.3 cm from the axis: hence 11.5 cm). The table is the floor below."""
FLOOR = CUP_CLEARANCE
"""The lowest the cup's centre goes (m above the table top)."""
WRIST_LEVER = 0.26
"""m from the cup's centre up its axis to the hand (link 7's origin)."""
REACH_SHOULDER = np.array([0.0, 0.0, 0.333])
"""Joint 2's axis (m), the centre of the reachable sets' shell."""


@dataclasses.dataclass(frozen=True)
class ReachSet:
    """A reachable set as the v2 planner uses it: the cup's position in [``low``, ``high``], the
    hand (``WRIST_LEVER`` up the cup's axis) between ``inner`` and ``radius`` m from the shoulder
    (``REACH_SHOULDER``), −angle ≤ roll ≤ ``roll_high`` (≤ angle) and −angle ≤ pitch ≤ angle
    (rad; the planner widens the box to contain its start). ``source``: the command that derived
    it from the arm model."""

    low: np.ndarray
    high: np.ndarray
    inner: float
    radius: float
    angle: float
    source: str
    roll_high: float | None = None
    """The roll's upper bound where it is tighter than ``angle`` (rad): the side on which the
    arm's wrist turns towards its singularity; None: ``angle``."""


REACH_SOURCE = (
    "lab/study/study_reach.py --samples 2000 --seed 0 (2026-11-25; IK on the scene's Panda "
    "from the home joints, every joint 0.1 rad inside its limits, the elbow 0.35 rad more from "
    "stretched, the wrist 25° from its singularity; the largest candidate set with ≥ 98 % of "
    "its drawn poses and of its outer 5 cm reachable, its floor raised until its floor corners "
    "keep the cup 1.6 cm off the table, 3 cm more where the arm cannot reach them); then "
    "(2026-11-26) room left for a person's push (study_reach.py's PUSH_ROOM: the shell's radius "
    "5.5 / 5 cm in, the floor at 15 / 18 cm, Tasks 2-3's far and high faces 6 and 8 cm in "
    "and the roll ≤ 0.1 rad), measured with lab/study/study_v2_pushes.py at seeds 36 and 38"
)
REACH_UPRIGHT = ReachSet(
    np.array([0.25, -0.45, 0.15]), np.array([0.80, 0.65, 0.60]), 0.35, 0.72, 0.0, REACH_SOURCE
)
"""Task 1's reachable set (the cup upright). The IK's set (of 2,000 drawn poses 1,108 inside it,
98.9 % of them and of its outer 5 cm reachable) reached 0.775 m and the floor (8 cm): pushes there
stretched the elbow to its limit or pressed the cup into the table, and u_H read them 15-34° off
the push (13 of 153 at seed 36; 1 of 165 with the room left)."""
REACH_TURNING = ReachSet(
    np.array([0.25, -0.45, 0.18]),
    np.array([0.74, 0.50, 0.62]),
    0.45,
    0.70,
    0.4,
    REACH_SOURCE,
    roll_high=0.1,
)
"""Tasks 2-3's reachable set (the cup turned). The IK's set (of 2,000 drawn poses 252 inside it,
98.0 % of them and of its outer 5 cm reachable) had its floor at 12 cm, not ``FLOOR``: at 8 cm
the arm could not reach the corner (0.27, 0.5, 0.08) m with roll and pitch 0.4 rad, stopped short
and put the cup on the table (19 and 21 of 200 seeds on Tasks 2 and 3). With room for a push:
the shell's radius 0.75 -> 0.70 m and the box's far and high faces 0.80 -> 0.74, 0.70 -> 0.62 m
(the elbow at its limit), the roll ≤ 0.1 rad (low over the table the cup rolled and pitched to
their positive side puts joints 5's and 7's axes within 1-10° of each other, the wrist's
singularity, where a torque turns the cup about another axis) and the floor 12 -> 18 cm (a push
down met the table):
seed 36's rotation within 30° 96.6 / 93.8 % -> 99.4 / 99.4 % on Tasks 2 / 3."""


SHELL_ROUNDS = 4
"""Rounds of projecting a waypoint into the shoulder's shell and then the box: one left the
box's corners 1-2 cm outside the shell."""


def _keep_out_walk(
    hulls: np.ndarray,
    shoulder: np.ndarray,
    radius: float,
    inner: float,
    lever: float,
    angle_scale: float,
    yaw: np.ndarray | None,
    low: np.ndarray,
    high: np.ndarray,
) -> Callable[[np.ndarray, float], None]:
    """The planner's constraint beyond its box (``strol_gym.planning.WalkFn``) for the
    reachable set and the keep-out cylinders. Positions are the first three coordinates
    (unscaled in the planner's frame), roll and pitch the next two (times ``angle_scale``),
    yaw (B,) held.

    Each waypoint after x0, all at once: the hand (``lever`` m up the cup's axis) is pulled
    into the shell ``inner`` ≤ distance ≤ ``radius`` around ``shoulder`` (alternating with the
    box); a cup inside a hull leaves it by the shorter way (out to its side, or up
    over its top); back into the box ``low``-``high``; a cup the box put back into a hull is
    lifted over it; then the plans are walked at the step bound, in the box and out of the
    hulls (``_walk_out``: the lift can lengthen a step at a hull's edge). Walking only the
    planner's result, not every iterate, is 4x cheaper and loses most of θ*'s return in Task 1
    (0.35 against 0.99): the ascent must see the robot's pace near a hull."""
    cx, cy, rad, top = (hulls[:, i : i + 1] for i in range(4))  # (k, 1): against (…, T)
    lo3, hi3 = low[:3], high[:3]

    def axis(p: np.ndarray) -> np.ndarray | float:
        """lever × the cup's axis (R e_z) for waypoints p (B, S, T, s)."""
        if yaw is None:
            return np.array([0.0, 0.0, lever])
        r, q = p[..., 3] * angle_scale, p[..., 4] * angle_scale
        y = yaw[:, None, None]
        cr, sr, cq, sq, cyw, syw = np.cos(r), np.sin(r), np.cos(q), np.sin(q), np.cos(y), np.sin(y)
        return lever * np.stack(
            [cyw * sq * cr + syw * sr, syw * sq * cr - cyw * sr, cq * cr], axis=-1
        )

    def walk(pos: np.ndarray, bound: float) -> None:
        if use_fast() and pos.dtype == np.float64 and pos.flags.c_contiguous:
            walk_compiled(pos, bound)
            return
        if yaw is not None:  # roll and pitch into the box at the robot's pace, first: the
            # hand's place below depends on them
            turn = pos[..., 3:5]
            way_turn = turn[..., 1:, :]
            # np.minimum(np.maximum(…)), as np.clip but without its Python layer: a third of
            # the walk's time at the planner's sizes; the same numbers
            np.maximum(way_turn, low[3:5] / angle_scale, out=way_turn)
            np.minimum(way_turn, high[3:5] / angle_scale, out=way_turn)
            for t in range(1, turn.shape[-2]):
                prev = turn[..., t - 1, :]
                turn[..., t, :] = prev + np.minimum(
                    np.maximum(turn[..., t, :] - prev, -bound), bound
                )
        way = pos[..., 1:, :]
        p = way[..., :3]
        off = axis(way)
        # the shell itself, whatever the start (``_walk_out`` then walks a start outside it in
        # at the robot's pace): a start beyond it let v2's first plans reach 0.8 m everywhere
        for _ in range(SHELL_ROUNDS):  # alternate: the box can push it back out of the shell
            arm = p + off - shoulder
            far = np.maximum(np.linalg.norm(arm, axis=-1, keepdims=True), 1e-12)
            p[:] = shoulder - off + arm * np.minimum(np.maximum(1.0, inner / far), radius / far)
            np.minimum(np.maximum(p, lo3, out=p), hi3, out=p)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        for k in range(len(rad)):
            dx, dy = x - cx[k], y - cy[k]
            rho = np.maximum(np.hypot(dx, dy), 1e-12)
            side, lift = rad[k] - rho, top[k] - z  # how far out, how far up
            inside = (side > 0) & (lift > 0)
            if not inside.any():
                continue
            sideways = inside & (side < lift)
            grow = rad[k] / rho
            # where, not a factor 1 elsewhere: cx + dx·1 can differ from x in its last bit, so
            # a row's plan depended on whether another row of the batch met the hull
            x[:] = np.where(sideways, cx[k] + dx * grow, x)
            y[:] = np.where(sideways, cy[k] + dy * grow, y)
            z[:] = np.where(inside & ~sideways, top[k], z)
        np.minimum(np.maximum(p, lo3, out=p), hi3, out=p)
        for k in range(len(rad)):
            inside = (np.hypot(x - cx[k], y - cy[k]) < rad[k]) & (z < top[k])
            z[:] = np.where(inside, top[k], z)
        pos[...] = _walk_out(pos, hulls, bound, lo3, hi3)  # at the robot's pace

    turn_low, turn_high = low[3:5] / angle_scale, high[3:5] / angle_scale

    def walk_compiled(pos: np.ndarray, bound: float) -> None:
        """``walk`` in compiled loops (``study_kernels``; the same bytes), φ's axis in numpy."""
        from strol_gym.tasks import study_kernels as kernels

        rows = pos.reshape(-1, *pos.shape[-2:])  # a view: pos is contiguous
        if yaw is not None:
            kernels.walk_turn(rows, turn_low, turn_high, bound)
        off = np.broadcast_to(axis(pos[..., 1:, :]), (*pos.shape[:-1][:-1], pos.shape[-2] - 1, 3))
        off = np.ascontiguousarray(off).reshape(rows.shape[0], -1, 3)
        kernels.walk_shell(rows, off, shoulder, inner, radius, SHELL_ROUNDS, hulls, lo3, hi3)
        # in place: step t reads its own planned waypoint before writing it
        kernels.walk_out(rows, rows, hulls, bound, lo3, hi3, WALK_ROUNDS, _per_first(pos))

    return walk


WALK_ROUNDS = 3
"""Rounds of pushing a step back onto the hulls' half-spaces along the box's free coordinates
(``_walk_out``): each round can hold one more face, and a box has three axes. Over 25 random
sets of 8 plans from random starts (mean return / |θ|), one round lost return beside the
faces: Task 2 6.544 against 6.555 with three (6.551 with two, 6.553 with five, 6.556 before
the walk kept the box); Task 1 6.877 against 6.886 (6.892, 6.890; 6.883 before)."""


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a · b over the last axis (3), broadcast: elementwise products added in order, the same
    bits in any batch (a reduction's order can depend on the operands' shapes)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _walk_out(
    plans: np.ndarray, hulls: np.ndarray, bound: float, low: np.ndarray, high: np.ndarray
) -> np.ndarray:
    """Plans (..., T+1, s) walked step by step at the step ``bound`` per position axis, every
    waypoint in the box ``low``-``high`` (positions, widened per plan to hold its start, as
    the planner's box is) and out of every hull that the one before it was out of.

    Each step heads for the planned waypoint and lands in three convex sets that all hold the
    previous waypoint: the step box (± ``bound``), the box, and each hull's supporting
    half-space at the previous waypoint's nearest hull point (towards the hull by at most the
    clearance it had: the hull is convex, so the waypoint stays outside). The step is clipped
    into the box, then pushed back onto a half-space it crossed along the hull's normal less
    the coordinates held at a box face the normal points out of, and clipped again
    (``WALK_ROUNDS``: the step slides along the face; beside Task 1's pitcher, which pokes
    out of the box's low x, it rises over the hull instead of going round outside the box, up
    to 5.4 cm out before); what is left over is taken off by shortening the step towards the
    previous waypoint, which keeps it in all three sets. A waypoint rounded into a hull (on
    its surface) stays where the last one was. A start inside a hull is walked out along the
    nearer face's normal, up to the bound per step, as far as the box lets it.

    The planner's per-waypoint projection can lengthen a step at a hull's edge; this pass keeps
    the plan at the robot's pace, in the box and out of the hulls. With the compiled kernels
    (``strol_gym.compiled``) one loop does it (``study_kernels.walk_out``, the same bytes).

    The plans along ``plans``' first axis are walked apart (one θ's plans, or its planner's
    starts, together: whether a round of pushing or the shortening runs is decided per first
    index, and a plan with none is left as it is): a θ's plans do not depend on the batch."""
    if use_fast() and plans.dtype == np.float64 and plans.ndim >= 2 and plans.shape[-1] >= 3:
        from strol_gym.tasks.study_kernels import walk_out

        rows = np.ascontiguousarray(plans).reshape(-1, *plans.shape[-2:])
        walked = rows.copy()
        f64 = np.float64
        walk_out(
            rows,
            walked,
            np.ascontiguousarray(hulls, dtype=f64),
            float(bound),
            np.ascontiguousarray(low, dtype=f64),
            np.ascontiguousarray(high, dtype=f64),
            WALK_ROUNDS,
            _per_first(plans),
        )
        return walked.reshape(plans.shape)
    out = plans.copy()
    p = out[..., :3]
    lo, hi = np.minimum(low, p[..., 0, :]), np.maximum(high, p[..., 0, :])  # hold the start
    centre, rad, top = hulls[:, :2], hulls[:, 2], hulls[:, 3]  # all hulls at once: (..., k)
    for t in range(1, out.shape[-2]):
        prev = p[..., t - 1, :]
        away = prev[..., None, :2] - centre
        rho = np.maximum(np.hypot(away[..., 0], away[..., 1]), 1e-12)
        dr, dz = rho - rad, prev[..., None, 2] - top
        outside = (dr > 0) | (dz > 0)
        clear = np.where(
            outside, np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0)), np.maximum(dr, dz)
        )
        # the normal: beside the hull out, above it up, off its rim between; inside, the
        # nearer face's. Not (dr, dz) scaled up from a floor: on the surface (dr or dz ~1e-17)
        # that made it ~1e-5 long, and the step went into the hull
        edge = (dr > 0) & (dz > 0)
        side = np.where(edge, dr, dr > dz)
        up = np.where(edge, dz, dr <= dz)
        norm = np.hypot(side, up)  # ≥ 1, or on the rim ≥ the spacing of doubles near it
        n = np.empty((*away.shape[:-1], 3))  # (..., k, 3): each hull's outward normal
        n[..., :2] = away * (side / (rho * norm))[..., None]
        n[..., 2] = up / norm
        need = np.minimum(-clear, bound)  # n·step ≥ need: prev is in it where need ≤ 0
        q = np.minimum(np.maximum(plans[..., t, :3] - prev, -bound), bound)  # np.clip, faster
        q += prev
        np.minimum(np.maximum(q, lo, out=q), hi, out=q)
        short = need - _dot3(n, (q - prev)[..., None, :])  # > 0: the step crosses it
        active = _any_per_first(short > 0, q.ndim)
        pushed = active.copy()
        for _ in range(WALK_ROUNDS):
            if not active.any():
                break
            # back onto each half-space along its normal, less the coordinates held at a box
            # face the normal points out of: there the step slides along the face (beside the
            # pitcher, where it pokes out of the box, it rises instead of leaving the box)
            held = ((q <= lo)[..., None, :] & (n < 0)) | ((q >= hi)[..., None, :] & (n > 0))
            free = np.where(held, 0.0, n)
            room = _dot3(free, n)  # 1 where nothing is held
            room = np.where(held.any(-1), room, 1.0)
            ok = (short > 0) & (room > 1e-9)  # room 0: every way back is held, none taken
            push = np.where(ok, short / np.where(ok, room, 1.0), 0.0)[..., None] * free
            moved = q.copy()
            for k in range(len(rad)):  # hull by hull: the same bits in any batch
                moved += push[..., k, :]
            np.minimum(np.maximum(moved, lo, out=moved), hi, out=moved)
            q = np.where(active, moved, q)
            short = need - _dot3(n, (q - prev)[..., None, :])
            active &= _any_per_first(short > 0, q.ndim)
        if pushed.any():  # shorten the step towards prev: into the step box and each
            # half-space prev is in (beyond rounding: the hull test below catches a waypoint
            # rounded in)
            step = q - prev
            scale = np.minimum(1.0, bound / np.maximum(np.abs(step).max(-1), 1e-12))
            cut = (need <= 0) & (short > 1e-12)
            frac = np.where(cut, -need / np.where(cut, short - need, 1.0), 1.0)
            scale = np.minimum(scale, frac.min(-1))  # 1 where nothing is cut: scale ≤ 1 kept
            q = np.where(pushed, prev + step * scale[..., None], q)
        # q is between prev and a point of the box: in the box within rounding. A waypoint
        # rounded into a hull that prev was outside of (q on its surface) stays at prev
        gone = q[..., None, :2] - centre
        into = (np.hypot(gone[..., 0], gone[..., 1]) < rad) & (q[..., None, 2] < top) & outside
        p[..., t, :] = np.where(into.any(-1)[..., None], prev, q)
    return out


def _any_per_first(mask: np.ndarray, ndim: int) -> np.ndarray:
    """Whether any entry of ``mask`` is set, per index of its first axis, shaped to broadcast
    against an array of ``ndim`` axes with the same first axis (``_walk_out``'s groups)."""
    if ndim <= 1:  # one plan: one group
        return np.asarray(mask.any())
    return mask.reshape(len(mask), -1).any(1).reshape((len(mask),) + (1,) * (ndim - 1))


def _per_first(plans: np.ndarray) -> int:
    """How many (T+1, s) plans each index of ``plans``' first axis holds (1 for one plan)."""
    return max(1, int(np.prod(plans.shape[1:-2], dtype=np.int64))) if plans.ndim > 2 else 1


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTaskV2(StudyTask):
    """A study Task as StROL-Study-v2 plans it: the same features, θ*, prior and bounds, and a
    planner that keeps the cup where the arm reaches it (``reach_*``) and out of the objects'
    hulls (``keep_out``, ``floor``). Plain data: the Task knows no simulator; the numbers were
    computed from the arm model offline (``reach_source``: ``lab/study/study_reach.py``)."""

    keep_out: np.ndarray = dataclasses.field(default_factory=KEEP_OUT.copy)
    floor: float = FLOOR
    reach_low: np.ndarray = dataclasses.field(default_factory=lambda: REACH_UPRIGHT.low.copy())
    reach_high: np.ndarray = dataclasses.field(default_factory=lambda: REACH_UPRIGHT.high.copy())
    reach_shoulder: np.ndarray = dataclasses.field(default_factory=REACH_SHOULDER.copy)
    reach_radius: float = REACH_UPRIGHT.radius
    reach_inner: float = REACH_UPRIGHT.inner
    reach_angle: float = REACH_UPRIGHT.angle
    reach_roll_high: float | None = REACH_UPRIGHT.roll_high
    reach_source: ClassVar[str] = REACH_SOURCE
    """How the reachable set was derived (the command, its date and method)."""

    def __post_init__(self) -> None:
        """The set's angles: a roll bound outside ±``reach_angle`` would leave the planner's
        box empty or wider than the set; it fails here, naming the field."""
        angle = checks.number("reach_angle", self.reach_angle, low=0.0)
        if self.reach_roll_high is not None:
            checks.number("reach_roll_high", self.reach_roll_high, low=-angle, high=angle)

    @property
    def low(self) -> np.ndarray:
        """The reachable box's lower corner, above the floor (yaw unbounded)."""
        pos = np.maximum(self.reach_low, [-np.inf, -np.inf, self.floor])
        ang = [-self.reach_angle, -self.reach_angle, -np.inf][: self.state_dim - 3]
        return np.concatenate([pos, ang])

    @property
    def high(self) -> np.ndarray:
        roll = self.reach_angle if self.reach_roll_high is None else self.reach_roll_high
        ang = [roll, self.reach_angle, np.inf][: self.state_dim - 3]
        return np.concatenate([self.reach_high, ang])

    def _plan_walk(self, x0: np.ndarray) -> Callable[[np.ndarray, float], None]:
        return _keep_out_walk(
            np.asarray(self.keep_out, dtype=np.float64),
            np.asarray(self.reach_shoulder, dtype=np.float64),
            float(self.reach_radius),
            float(self.reach_inner),
            WRIST_LEVER,
            float(self._plan_scale[-1]),
            x0[:, 5] if self.oriented else None,
            self.low,
            self.high,
        )

    def plan(self, theta: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """``StudyTask.plan`` within the reachable set and out of the hulls (see the class)."""
        plans = super().plan(theta, x0)
        hulls = np.asarray(self.keep_out, dtype=np.float64)
        return _walk_out(plans, hulls, self.plan_pos_bound, self.low[:3], self.high[:3])

    def around_hulls(self, path: np.ndarray) -> np.ndarray:
        """A path (T+1, s) walked at the planner's step around the hulls (``_walk_out``) within
        the reachable box widened to hold both its ends, then straight on to its last pose if
        the walk fell short: the robot's way home, which a straight line took through the
        pitcher (v2's first runs: 13 of 200 seeds). Home may lie outside the box (Task 1's x,
        Tasks 2-3's y: by 0.3 and 6 cm)."""
        path = np.asarray(path, dtype=np.float64)
        end = path[-1, :3]
        low, high = np.minimum(self.low[:3], end), np.maximum(self.high[:3], end)
        hulls = np.asarray(self.keep_out, dtype=np.float64)
        walked = _walk_out(path[None], hulls, self.plan_pos_bound, low, high)[0]
        gap = path[-1, :3] - walked[-1, :3]
        n = int(np.ceil(np.max(np.abs(gap)) / self.plan_pos_bound - 1e-9))
        if n <= 0:
            return walked
        tail = walked[-1] + np.linspace(0.0, 1.0, n + 1)[1:, None] * (path[-1] - walked[-1])
        return np.vstack([walked, tail])

    def outside_hulls(self, x: np.ndarray) -> np.ndarray:
        """Whether each cup position (..., ≥3) is outside every hull and above the floor."""
        x = np.asarray(x, dtype=np.float64)
        h = np.asarray(self.keep_out)
        rho = np.hypot(x[..., None, 0] - h[:, 0], x[..., None, 1] - h[:, 1])
        inside = (rho < h[:, 2]) & (x[..., None, 2] < h[:, 3])
        return ~inside.any(-1) & (x[..., 2] >= self.floor)

    @property
    def ghat_task(self) -> StudyTask:
        """StROL-Study-v2's own ĝ (``pretrained/study{1,2,3}-v2_*``, trained on the fitted
        population's corrections, docs/study.md)."""
        return self


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask1V2(StudyTaskV2, StudyTask1V1):
    """Task 1 as StROL-Study-v2 plans it (``StudyTaskV2``; the cup upright: ``REACH_UPRIGHT``)."""

    version: ClassVar[int] = 2


@dataclasses.dataclass(frozen=True, eq=False)
class _TurningV2(StudyTaskV2):
    """What v2's Tasks 2 and 3 share: the reachable set of a cup that turns and the 4-D prior."""

    reach_low: np.ndarray = dataclasses.field(default_factory=lambda: REACH_TURNING.low.copy())
    reach_high: np.ndarray = dataclasses.field(default_factory=lambda: REACH_TURNING.high.copy())
    reach_inner: float = REACH_TURNING.inner
    reach_radius: float = REACH_TURNING.radius
    reach_angle: float = REACH_TURNING.angle
    reach_roll_high: float | None = REACH_TURNING.roll_high

    prior: Prior = dataclasses.field(default_factory=_prior4)  # not StudyTaskV2's (Task 1's)


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask2V2(_TurningV2, StudyTask2V1):
    """Task 2 as StROL-Study-v2 plans it (``StudyTaskV2``; the cup turns: ``REACH_TURNING``)."""

    version: ClassVar[int] = 2


@dataclasses.dataclass(frozen=True, eq=False)
class StudyTask3V2(_TurningV2, StudyTask3V1):
    """Task 3 as StROL-Study-v2 plans it (``StudyTaskV2``; the cup turns: ``REACH_TURNING``)."""

    version: ClassVar[int] = 2


STUDY_TASKS_V2: dict[int, type[StudyTaskV2]] = {1: StudyTask1V2, 2: StudyTask2V2, 3: StudyTask3V2}

STUDY_TASK_SETS: dict[int, Mapping[int, type[StudyTask]]] = {
    tasks[1].version: tasks for tasks in (STUDY_TASKS, STUDY_TASKS_V1, STUDY_TASKS_V2)
}
"""Each study version's Tasks by number (``StudyVersion.tasks`` reads them; the Task registry
names them ``study_task_name``)."""
