"""The Robot setting: an end effector moving among a plate and a cup on a table.

Task frame: metres, x forward from the robot base, y to the left, z up from the table top.
State x is the end-effector position (3,). Actions are end-effector displacements per step,
bounded per axis by ``step_bound``. The transition used by the learning rule is
x' = clip(x + u_R + u_H, workspace), the kinematics that the MuJoCo env tracks with IK.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from typing import ClassVar

import numpy as np

from strol_gym.compiled import use_fast
from strol_gym.draws import uniform_rows
from strol_gym.planning import plan_linear_reward
from strol_gym.priors import MixturePrior, Prior
from strol_gym.tasks.base import Task, positive_field, vector_arg

PLATE = np.array([0.35, 0.10, 0.00])
CUP = np.array([0.70, -0.45, 0.10])
START = np.array([0.20, 0.20, 0.60])
ROBOT_MODES = np.array([[0.8, -0.8], [-0.8, 0.8]])
# The box the end effector moves in. The authors' point robot used [0, 0.8] x [-0.6, 0.4] x
# [0, 0.7]; a real Panda cannot reach all of that with its gripper pointing down (its far
# corners are ~1 m from any base position, and points next to the base are inside its inner
# dead zone). This box keeps the plate, the cup and the paper's start inside and is reachable
# from the base position that strol_gym.envs.robot uses (docs/robot.md, docs/fidelity.md).
WORKSPACE_LOW = np.array([0.15, -0.55, 0.0])
WORKSPACE_HIGH = np.array([0.75, 0.35, 0.7])
_PLANAR_MASK = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 1.0]])
_LONG = 3000
"""Array size from which φ and ∂φ/∂x work per object and axis (``RobotTask._offsets``)."""


_M6_METHODS = ("g", "g_planes", "features", "dynamics", "_offsets", "_features_one", "dynamics_one")
"""What ``robot_m6`` computes over again: a subclass overriding one of them takes the plain path."""


@functools.cache
def _drawn_kernel() -> Callable[..., None]:
    """``m6_kernels.robot_m6_drawn``, imported once (it loads numba; every correction asks)."""
    from strol_gym.tasks.m6_kernels import robot_m6_drawn

    return robot_m6_drawn


def _m6_layout(x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> bool:
    """x and u_R (B, 1, 3) with K candidate u_H (B, K, 3): eq. M6's layout."""
    if not x.ndim == u_h.ndim == u_r.ndim == 3:
        return False
    (b, one, a), (bh, _, ah), (br, one_r, ar) = x.shape, u_h.shape, u_r.shape
    return one == one_r == 1 and b == bh == br and a == ah == ar == 3


def _default_prior() -> Prior:
    return MixturePrior(ROBOT_MODES, jitter=0.1)


@dataclasses.dataclass(frozen=True, eq=False)
class RobotTask(Task):
    """φ(x) = (−‖x_xy − plate_xy‖, −‖x − cup‖): positive weights reach, negative avoid."""

    task_id: ClassVar[str] = "StROL-Robot-v0"
    version: ClassVar[int] = 0
    feature_names: ClassVar[tuple[str, ...]] = ("plate_planar_distance", "cup_distance")
    state_dim: ClassVar[int] = 3
    action_dim: ClassVar[int] = 3
    feature_high: ClassVar[float] = 0.0  # both features are negated distances

    prior: Prior = dataclasses.field(default_factory=_default_prior)
    alpha: float = 2.0
    plate: np.ndarray = dataclasses.field(default_factory=PLATE.copy)
    cup: np.ndarray = dataclasses.field(default_factory=CUP.copy)
    start: np.ndarray = dataclasses.field(default_factory=START.copy)
    workspace_low: np.ndarray = dataclasses.field(default_factory=WORKSPACE_LOW.copy)
    workspace_high: np.ndarray = dataclasses.field(default_factory=WORKSPACE_HIGH.copy)
    step_bound: float = 0.1
    plan_steps: int = 10
    plan_step_bound: float = 0.05

    def __post_init__(self) -> None:
        """Every field is checked: a NaN or nonsense value fails here, naming the field."""
        if not isinstance(self.prior, Prior) or self.prior.dim != 2:
            raise ValueError(f"prior must be a Prior over 2 weights, got {self.prior!r}")
        positive_field("alpha", self.alpha)
        for name in ("step_bound", "plan_step_bound"):
            positive_field(name, getattr(self, name))
        positive_field("plan_steps", self.plan_steps, integer=True)
        object.__setattr__(self, "plan_steps", int(self.plan_steps))
        for name in ("plate", "cup", "start", "workspace_low", "workspace_high"):
            object.__setattr__(self, name, vector_arg(name, getattr(self, name), 3).copy())
        lo, hi = self.workspace_low, self.workspace_high
        if not (lo < hi).all():
            raise ValueError(
                f"workspace_low must be below workspace_high on every axis, got {lo} and {hi}"
            )
        # The plate and the cup may lie outside the box (things to reach for or avoid), but
        # the end effector starts inside it.
        if not ((lo <= self.start) & (self.start <= hi)).all():
            raise ValueError(f"start must lie in the workspace box [{lo}, {hi}], got {self.start}")

    @property
    def action_bound(self) -> np.ndarray:
        return np.full(3, self.step_bound)

    @property
    def prior_modes(self) -> np.ndarray:
        return ROBOT_MODES

    @property
    def feature_scale(self) -> np.ndarray:
        # Both features are distances in metres across the same workspace: one scale.
        return np.ones(2)

    @functools.cached_property
    def _objects(self) -> np.ndarray:
        """(2, 3): the plate (row 0, whose z is masked out: planar distance) and the cup."""
        return np.stack([self.plate, self.cup])

    def features(self, x: np.ndarray) -> np.ndarray:
        if type(x) is np.ndarray and x.dtype == np.float64:
            if x.shape == (3,):
                return np.array(self._features_one(*x.tolist()))
            if x.ndim == 2 and x.shape[1] == 3 and len(x) > 1:
                kernel = _features_kernel(self)
                if kernel is not None:  # a vector env's states: one compiled call
                    out = np.empty((len(x), 2))
                    kernel(x, self._objects, out)
                    return out
        return self._features_numpy(x)

    def _features_numpy(self, x: np.ndarray) -> np.ndarray:
        diff = self._offsets(np.asarray(x, dtype=np.float64))  # (..., 2, 3)
        # C order whatever the layout of diff: sums over φ (returns, plan values) reduce in
        # memory order, and the same layout gives the same rounding.
        return -np.sqrt(np.einsum("...ij,...ij->...i", diff, diff, order="C"))

    def _features_one(self, x0: float, x1: float, x2: float) -> tuple[float, float]:
        """φ of one state in plain floats (the env's every step: numpy's per-call cost dominates
        on 3 numbers). The same IEEE operations in the order of ``features``' sum over the 3
        axes, (d0² + d2²) + d1², so the same bits; the plate's masked d2² is +0, which adds
        nothing."""
        (p0, p1, _), (c0, c1, c2) = self._objects_l
        d0, d1 = p0 - x0, p1 - x1
        e0, e1, e2 = c0 - x0, c1 - x1, c2 - x2
        return (-math.sqrt(d0 * d0 + d1 * d1), -math.sqrt((e0 * e0 + e2 * e2) + e1 * e1))

    @functools.cached_property
    def _objects_l(self) -> list[list[float]]:
        return self._objects.tolist()

    def feature_jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂φ/∂x, (..., 3) -> (..., 2, 3), for gradient-based planning (0 at the kinks).

        On large batches a view of an object-major array (``_offsets``): fine for elementwise
        use, as the planner's; copy it (``np.ascontiguousarray``) before reducing over it."""
        diff = self._offsets(np.asarray(x, dtype=np.float64))  # −∂φ/∂x · dist; in place below
        dist = np.sqrt(np.einsum("...ij,...ij->...i", diff, diff))
        np.maximum(dist, 1e-12, out=dist)
        if diff.size < _LONG:
            diff /= dist[..., None]
        else:
            for o, c in np.ndindex(_PLANAR_MASK.shape):
                diff[..., o, c] /= dist[..., o]
        return diff

    def _offsets(self, x: np.ndarray) -> np.ndarray:
        """(objects − x) · mask, (..., 3) -> (..., 2, 3).

        The env calls φ on one state (one broadcast is cheapest); the planner on thousands.
        Then it works per object and axis, and the result is laid out object-major (a view
        of a (2, ..., 3) array), so that ``jac[..., i, :]`` is contiguous for the planner's
        θ-weighted sum: broadcasting makes numpy's inner loops 3 elements long, several times
        slower. The same numbers either way.
        """
        if x.size < _LONG:
            return (self._objects - x[..., None, :]) * _PLANAR_MASK
        diff = np.moveaxis(np.empty((2, *x.shape)), 0, -2)
        for (o, c), mask in np.ndenumerate(_PLANAR_MASK):
            out = np.subtract(self._objects[o, c], x[..., c], out=diff[..., o, c])
            if mask != 1.0:
                out *= mask
        return diff

    def dynamics(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        if (  # one state (the env's every step) in plain floats
            type(x) is np.ndarray
            and type(u_h) is np.ndarray
            and type(u_r) is np.ndarray
            and x.shape == u_h.shape == u_r.shape == (3,)
        ):
            return np.array(self.dynamics_one(x.tolist(), u_h.tolist(), u_r.tolist()))
        return np.minimum(np.maximum(x + u_r + u_h, self.workspace_low), self.workspace_high)

    def dynamics_one(self, x: list[float], u_h: list[float], u_r: list[float]) -> list[float]:
        """f of one state in plain floats: the same IEEE operations as ``dynamics``."""
        out = []
        for xi, hi_, ri, lo, hi in zip(x, u_h, u_r, self._low_l, self._high_l, strict=True):
            v = xi + ri + hi_
            v = lo if v < lo else v
            out.append(hi if v > hi else v)
        return out

    @functools.cached_property
    def _low_l(self) -> list[float]:
        return self.workspace_low.tolist()

    @functools.cached_property
    def _high_l(self) -> list[float]:
        return self.workspace_high.tolist()

    def g(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """φ(x_H) − φ(x_R) (eq. P3). For eq. M6's layout, x and u_R (B, 1, 3) with K candidate
        u_H (B, K, 3), through ``g_planes`` (the same numbers, laid out (B, K, 2))."""
        x, u_h, u_r = (np.asarray(a, dtype=np.float64) for a in (x, u_h, u_r))
        if not _m6_layout(x, u_h, u_r):
            return super().g(x, u_h, u_r)
        return np.ascontiguousarray(self.g_planes(x, u_h, u_r).transpose(1, 2, 0))

    def g_planes(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """g of eq. M6's layout as (d, B, K) planes, one contiguous (B, K) plane per feature and
        state axis: broadcasting over a last axis of 3 makes numpy's inner loops 3 elements
        long, several times slower. The same IEEE operations as ``dynamics`` and ``features``,
        so the same numbers as ``g`` on any layout."""
        x, u_h, u_r = (np.asarray(a, dtype=np.float64) for a in (x, u_h, u_r))
        if not _m6_layout(x, u_h, u_r):
            return super().g_planes(x, u_h, u_r)
        base = x + u_r  # (B, 1, 3): x + u_R, then + u_H as ``dynamics`` adds them
        x_h = np.empty((3, *u_h.shape[:2]))
        np.add(base.transpose(2, 0, 1), u_h.transpose(2, 0, 1), out=x_h)
        np.maximum(x_h, self._box_planes[0], out=x_h)
        np.minimum(x_h, self._box_planes[1], out=x_h)
        phi_r: tuple[float, float] | np.ndarray
        if len(x) == 1:  # one state: φ(x_R) in plain floats, subtracted as scalars
            zero = [0.0, 0.0, 0.0]
            phi_r = self._features_one(
                *self.dynamics_one(x[0, 0].tolist(), zero, u_r[0, 0].tolist())
            )
        else:
            phi_r = self.features(self.dynamics(x[:, 0], np.zeros_like(x[:, 0]), u_r[:, 0])).T[
                :, :, None
            ]
        out = np.empty((2, *u_h.shape[:2]))
        # Squares summed as ``features``' reduction does: (d0² + d2²) + d1²; the plate's
        # masked d2² is +0 and adds nothing.
        d = np.subtract(self._object_planes[0][:2], x_h[:2])
        d *= d
        plate = np.add(d[0], d[1], out=out[0])
        np.sqrt(plate, out=plate)
        np.negative(plate, out=plate)
        plate -= phi_r[0]
        e = np.subtract(self._object_planes[1], x_h)
        e *= e
        cup = np.add(e[0], e[2], out=out[1])
        cup += e[1]
        np.sqrt(cup, out=cup)
        np.negative(cup, out=cup)
        cup -= phi_r[1]
        return out

    def m6_choice(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_hat: np.ndarray,
        theta_star: np.ndarray,
        candidates: np.ndarray,
    ) -> np.ndarray | None:
        """Eq. M6 by ``strol_gym.tasks.m6_kernels.robot_m6`` (the numbers of ``g_planes``)."""
        if not self._unchanged(RobotTask, _M6_METHODS):
            return None
        from strol_gym.tasks.m6_kernels import robot_m6

        best = np.empty(len(candidates), dtype=np.int64)
        c = np.ascontiguousarray
        robot_m6(
            c(x, dtype=np.float64),
            c(u_r, dtype=np.float64),
            c(theta_hat, dtype=np.float64),
            c(theta_star, dtype=np.float64),
            c(candidates, dtype=np.float64),
            *self._m6_params,
            best,
        )
        return best

    def m6_drawn(self) -> Callable[..., None] | None:
        """``_m6_drawn`` while ``m6_choice`` runs its kernel and the candidates and the noise's
        scale are ``Task``'s."""
        return self._drawn_while(RobotTask, _M6_METHODS, self._m6_drawn)

    def _m6_drawn(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_hat: np.ndarray,
        theta_star: np.ndarray,
        units: np.ndarray,
        noise: np.ndarray,
        sigma: float,
        bias: float,
        out: np.ndarray,
    ) -> None:
        """``Task.m6_drawn`` by ``strol_gym.tasks.m6_kernels.robot_m6_drawn``."""
        prm = self.m6_drawn_params(sigma, bias)
        _drawn_kernel()(x, u_r, theta_hat, theta_star, units, noise, prm, out)

    def m6_drawn_params(self, sigma: float, bias: float) -> np.ndarray:
        """What ``robot_m6_drawn`` reads of the Task and the noise, in its order: α, σ, ε, the
        plate, the cup, the box's corners, the candidates' bound and a_max (once per σ, ε)."""
        memo = self.__dict__.setdefault("_m6_drawn_memo", {})  # as ``_unchanged``'s
        prm = memo.get((sigma, bias))
        if prm is None:
            alpha, plate, cup, low, high = self._m6_params
            prm = memo[sigma, bias] = np.concatenate(
                [[alpha, sigma, bias], plate, cup, low, high, self._axis_scale, self.a_max]
            ).astype(np.float64)
        return prm

    @functools.cached_property
    def _m6_params(self) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What ``robot_m6`` reads of the Task, in its order: α, plate, cup, the box's corners."""
        return (float(self.alpha), self.plate, self.cup, self.workspace_low, self.workspace_high)

    @functools.cached_property
    def _box_planes(self) -> np.ndarray:
        """(2, 3, 1, 1): the workspace box's low and high corners, one number per axis plane."""
        return np.stack([self.workspace_low, self.workspace_high])[:, :, None, None]

    @functools.cached_property
    def _object_planes(self) -> np.ndarray:
        """(2, 3, 1, 1): the plate and the cup, one number per axis plane."""
        return self._objects[:, :, None, None]

    def plan(self, theta: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Plans maximising Σ_{t=1..T} θ·φ(x_t): (B, 2), (B, 3) -> (B, T+1, 3), T = plan_steps.

        Per-axis step ≤ ``plan_step_bound``; waypoints stay inside the workspace box during the
        optimisation (strol_gym.planning). Deterministic: starts are seeded internally.
        """
        return plan_linear_reward(
            self.features,
            self.feature_jacobian,
            theta,
            x0,
            steps=self.plan_steps,
            step_bound=self.plan_step_bound,
            low=self.workspace_low,
            high=self.workspace_high,
            targets=self._plan_targets,
            away=False,
            # Measured on 300 random (θ, x0) problems: with 8 random starts, 60 iterations and
            # 4 starts kept, 10 % of plans fell > 1e-3 short of the best plan any setting found
            # (such a shortfall can flip the plan's regime and cost regret ~0.4); with these, 1 %.
            n_random=16,
            n_iters=100,
            keep=8,
        )

    @functools.cached_property
    def _plan_targets(self) -> np.ndarray:
        """Where the planner's straight-line starts head: the cup, the plate at the table and
        at the box's top (its feature ignores height), and the box's 8 corners (the far points
        that "stay away" weights want). Without them the ascent can settle in a worse corner."""
        lo, hi = self.workspace_low, self.workspace_high
        plate_top = np.array([*self.plate[:2], hi[2]])
        corners = np.array([[(lo, hi)[(i >> k) & 1][k] for k in range(3)] for i in range(8)])
        return np.vstack([self.plate, plate_top, self.cup, corners])

    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return self._in_box(rng.random((n, 3)))

    def sample_starts(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        if type(self).sample_start is not RobotTask.sample_start:
            return super().sample_starts(rngs)
        return self._in_box(uniform_rows(rngs, np.empty((len(rngs), 3))))

    def _in_box(self, unit: np.ndarray) -> np.ndarray:
        """Uniform draws in [0, 1) mapped into the workspace box: what ``rng.uniform(low, high)``
        computes, low + (high − low)·U, from the same draws (the same numbers), without its
        cost of broadcasting array bounds."""
        lo = self.workspace_low
        return lo + (self.workspace_high - lo) * unit


@functools.cache
def _features_checked() -> Callable | None:
    """``m6_kernels.robot_features`` where it gives numpy's φ (``RobotTask._features_numpy``,
    the sum over the axes in the order of numpy's einsum here) on probe states of both of
    its layouts, checked once per process; else None."""
    from strol_gym.tasks.m6_kernels import robot_features

    task = RobotTask()
    for n in (5, 1100):  # below and above _LONG numbers
        x = np.random.default_rng(n).uniform(-2.0, 2.0, (n, 3))
        out = np.empty((n, 2))
        robot_features(x, task._objects, out)
        if out.tobytes() != task._features_numpy(x).tobytes():
            return None
    return robot_features


_FEATURES = ("_features_numpy", "_offsets", "_features_one", "_objects")
"""What ``robot_features`` computes over again of ``RobotTask``."""


def _features_kernel(task: RobotTask) -> Callable | None:
    """The compiled φ of many states, or None: the plain kernels, a Task class that changes
    what it repeats, or numpy summing in another order here."""
    if not (use_fast() and task._unchanged(RobotTask, _FEATURES)):
        return None
    return _features_checked()
