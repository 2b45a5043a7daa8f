"""The Task: everything true of a setting whatever simulates it.

φ (features), the state transition f used by the learning rule, g = φ(x_H) − φ(x_R), the prior,
the action bound, the start distribution and the planner. The env, the humans, the learners,
training and the benchmark all read these from one Task object, and every array method is
batched: leading dimensions broadcast, the last axis is the state / action / feature axis.
"""

from __future__ import annotations

import dataclasses
import functools
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import ClassVar

import numpy as np

from strol_gym import checks
from strol_gym.compiled import use_fast
from strol_gym.priors import Prior

DRAWN_METHODS = ("candidate_actions", "_unit_to_box", "_axis_scale", "a_max", "a_max_l")
"""What a Task's compiled ``m6_drawn`` computes over again of ``Task``: the candidates and the
noise's scale (a subclass overriding one of them takes the plain path)."""


def _jsonable(value: object) -> object:
    """Arrays and tuples as lists, numpy scalars as Python numbers: for JSON records."""
    if isinstance(value, np.ndarray | tuple | list):
        return np.asarray(value).tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def positive_field(name: str, value: object, *, integer: bool = False) -> float:
    """A Task field that must be a finite number > 0 (an integer >= 1 if ``integer``)."""
    if integer:
        return checks.number(name, value, low=1, integer=True)
    return checks.number(name, value, low=0, low_open=True)


def vector_arg(name: str, value: object, n: int) -> np.ndarray:
    """``n`` finite numbers (any shape holding n) as a fresh float64 vector, else ValueError
    naming the argument: for Task fields and env arguments alike."""
    return checks.vector(name, value, n)


def unique_rows(*arrays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct rows of ``arrays`` side by side, compared by their exact bytes: (indices of each
    distinct row's first occurrence, for every row the position of its own among those).

    Bytes, not values: −0.0 and 0.0 stay apart, so a deduplicated computation
    returns the very numbers the full one would.
    """
    index: dict[bytes, int] = {}
    first: list[int] = []
    inverse = np.empty(len(arrays[0]), dtype=np.intp)
    for i in range(len(inverse)):
        key = b"".join(np.ascontiguousarray(a[i]).tobytes() for a in arrays)
        j = index.setdefault(key, len(first))
        if j == len(first):
            first.append(i)
        inverse[i] = j
    return np.asarray(first, dtype=np.intp), inverse


@dataclasses.dataclass(frozen=True, eq=False)
class Task(ABC):
    """Base class for a StROL setting. Subclasses are frozen dataclasses, so they pickle.

    Class attributes a subclass sets: ``task_id``, ``version``, ``feature_names``,
    ``state_dim``, ``action_dim`` (and ``feature_high`` if its features are bounded above).
    Instance fields: ``prior`` (P(θ*)), ``alpha`` (the learning rate α of eq. P2) and whatever
    geometry the setting needs.
    """

    task_id: ClassVar[str]
    version: ClassVar[int]
    feature_names: ClassVar[tuple[str, ...]]
    state_dim: ClassVar[int]
    action_dim: ClassVar[int]
    feature_high: ClassVar[float] = np.inf
    """An upper bound of every feature (the top of the envs' ``"phi"`` observation box)."""
    weights_stem: ClassVar[str | None] = None
    """The stem of its shipped ĝ files, ``<stem>_<kind>.safetensors`` (None: its registry
    name). The files are found by their sidecars' ``task_id``; the stem only names them."""

    prior: Prior
    alpha: float

    # ----------------------------------------------------------------- what subclasses define
    @property
    @abstractmethod
    def action_bound(self) -> np.ndarray:
        """a_max per action axis, shape (action_dim,): the largest admissible |u| per axis."""

    @property
    @abstractmethod
    def prior_modes(self) -> np.ndarray:
        """The modes of the paper's bimodal prior for this setting, shape (k, d)."""

    @property
    @abstractmethod
    def feature_scale(self) -> np.ndarray:
        """A typical range of each feature, shape (d,), so features can be compared (One)."""

    @abstractmethod
    def features(self, x: np.ndarray) -> np.ndarray:
        """φ(x): (..., state_dim) -> (..., d)."""

    @abstractmethod
    def dynamics(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """f(x, u_H, u_R): (..., state_dim), (..., action_dim) x2 -> (..., state_dim)."""

    @abstractmethod
    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Draw ``n`` start states, shape (n, state_dim)."""

    def sample_starts(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """``sample_start(rng, 1)`` for each generator, stacked: (len(rngs), state_dim).

        A vector env's resets, one sub-env per generator. Settings may override it to draw
        per generator and do the arithmetic once on the batch (the same numbers)."""
        return np.concatenate([self.sample_start(rng, 1) for rng in rngs])

    # ----------------------------------------------------------------- shared by every setting
    @property
    def dim(self) -> int:
        """d, the number of reward weights."""
        return len(self.feature_names)

    def reward(self, x: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """R(x, θ) = θ·φ(x), batched: (..., state_dim), (..., d) -> (...)."""
        return np.sum(self.features(x) * theta, axis=-1)

    def g(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """The original learning rule (eq. P3) for linear rewards: φ(x_H) − φ(x_R)."""
        x_h = self.dynamics(x, u_h, u_r)
        # x_R does not depend on u_H: compute it once per (x, u_R), not once per candidate u_H
        # (eq. M6 evaluates g for many candidates); features(x_R) broadcasts in the difference.
        x, u_r = np.asarray(x), np.asarray(u_r)
        lead = np.broadcast_shapes(x.shape[:-1], u_r.shape[:-1])
        x_r = self.dynamics(
            np.broadcast_to(x, (*lead, x.shape[-1])),
            np.zeros((*lead, np.shape(u_h)[-1])),
            np.broadcast_to(u_r, (*lead, u_r.shape[-1])),
        )
        return self.features(x_h) - self.features(x_r)

    def g_planes(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """``g`` with the feature axis first, (..., d) -> (d, ...): what eq. M6's search reads
        one feature at a time. A Task may compute it as contiguous planes (``RobotTask``);
        by default a view of ``g``."""
        g = self.g(x, u_h, u_r)
        return g.transpose(g.ndim - 1, *range(g.ndim - 1))

    def m6_choice(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_hat: np.ndarray,
        theta_star: np.ndarray,
        candidates: np.ndarray,
    ) -> np.ndarray | None:
        """Eq. M6's chosen candidate per person, (B,) indices, from a compiled kernel
        (``strol_gym.compiled``), or None: then ``optimal_correction``'s plain search runs. A
        Task offers a kernel only while the methods it repeats are its own (``_unchanged``)."""
        return None

    def m6_drawn(self) -> Callable[..., None] | None:
        """The eq. M6 teacher's noisy corrections straight from each person's draws, as one
        compiled call, or None (offered only where ``m6_choice`` is):
        ``f(x, u_r, theta_hat, theta_star, units, noise, sigma, bias, out)`` writes (B, a)
        into ``out``, from U (B, K, a) in [0, 1) as ``candidate_actions`` fills them and the
        noise z (B, a): the numbers of ``candidate_actions``, ``m6_choice`` and ``perturb``."""
        return None

    def _drawn_while(
        self, cls: type, names: Sequence[str], drawn: Callable[..., None]
    ) -> Callable[..., None] | None:
        """A Task's ``m6_drawn``: its ``drawn`` while ``names`` (what its kernel repeats)
        are ``cls``'s and the candidates and the noise's scale ``Task``'s (``DRAWN_METHODS``);
        asked on every correction, answered once per Task."""
        ok = self.__dict__.get("_m6_drawn_ok")
        if ok is None:  # (a frozen dataclass: as ``_unchanged``, into the instance dict)
            ok = self.__dict__["_m6_drawn_ok"] = self._unchanged(cls, names) and self._unchanged(
                Task, DRAWN_METHODS
            )
        return drawn if ok else None

    def _unchanged(self, cls: type, names: Sequence[str]) -> bool:
        """Whether this Task's ``names`` are ``cls``'s: a subclass that overrides one of them
        changes what a kernel written for ``cls`` would compute. Asked on every correction,
        answered once per Task (its class does not change)."""
        key = (cls, tuple(names))
        memo = self.__dict__.setdefault("_unchanged_memo", {})  # a frozen dataclass: as
        found = memo.get(key)  # functools.cached_property, straight into the instance dict
        if found is None:
            own = type(self)
            found = memo[key] = all(getattr(own, n) is getattr(cls, n) for n in names)
        return found

    @functools.cached_property
    def a_max(self) -> np.ndarray:
        """``action_bound`` computed once (read-only): the humans' noise scales by it on every
        correction, and a Task's fields do not change."""
        bound = np.array(self.action_bound)
        bound.flags.writeable = False
        return bound

    @functools.cached_property
    def a_max_l(self) -> list[float]:
        """``a_max`` as plain floats (one person's correction, where numpy's per-call cost
        dominates on a few numbers)."""
        return np.asarray(self.a_max, dtype=np.float64).tolist()

    def candidate_actions(self, rng: np.random.Generator, n: int, k: int) -> np.ndarray:
        """Candidate human actions for eq. M6, shape (n, k + 1, action_dim).

        ``k`` uniform draws from the admissible box, plus the zero action at index 0, so that
        "do nothing" is always available to the optimal human.
        """
        if k < 0:
            raise ValueError(f"k must be >= 0, got {k}")
        out = np.empty((n, k + 1, self.action_dim))
        out[:, 0] = 0.0
        # rng.uniform(-1, 1) computes −1 + 2·U from U in [0, 1): the same draws and numbers,
        # with numpy's cheaper fill of U, in place (one person's block is contiguous).
        u = out[:, 1:]
        if n == 1:
            rng.random(out=u[0])
        else:
            u[...] = rng.random((n, k, self.action_dim))
        self._unit_to_box(u)
        return out

    def _unit_to_box(self, u: np.ndarray) -> None:
        """U (n, k, action_dim) in [0, 1) to (−1 + 2U)·a_max, in place: the numbers
        ``rng.uniform(−1, 1)`` times the bound gives. Compiled kernels on
        (``strol_gym.compiled``): one pass (``m6_kernels.unit_to_box``, the same operations in
        the same order); else numpy's three passes (``_scale_candidates``)."""
        if use_fast() and u.dtype == np.float64 and u.ndim == 3:
            from strol_gym.tasks.m6_kernels import unit_to_box

            unit_to_box(u, self._axis_scale)
            return
        u *= 2.0
        u += -1.0
        self._scale_candidates(u)

    @functools.cached_property
    def _axis_scale(self) -> np.ndarray:
        """a_max per action axis, float64 and contiguous (what ``unit_to_box`` reads)."""
        return np.ascontiguousarray(self.a_max, dtype=np.float64)

    def _scale_candidates(self, u: np.ndarray) -> None:
        """u (n, k, action_dim) *= a_max, in place. One bound for every axis (the Robot's): a
        scalar product. Per axis (the Highway's): each person's block times the bound tiled k
        times, the same products, without broadcasting's inner loops as short as an action."""
        scale = self._candidate_scale
        if isinstance(scale, float):
            u *= scale
            return
        n, k, a = u.shape
        try:
            flat = np.reshape(u, (n, k * a), copy=False)  # refused where it would need a copy
        except ValueError:
            u *= scale
            return
        tiled = self.__dict__.setdefault("_tiled_scales", {}).get(k)
        if tiled is None:
            tiled = self.__dict__["_tiled_scales"][k] = np.tile(scale, k)
        flat *= tiled

    @functools.cached_property
    def _candidate_scale(self) -> float | np.ndarray:
        """a_max as one number when every axis shares it, else per axis."""
        bound = self.a_max
        return float(bound[0]) if (bound == bound[0]).all() else bound

    def with_prior(self, prior: Prior) -> Task:
        """The same setting with another prior over θ*."""
        if prior.dim != self.dim:
            raise ValueError(f"prior has dim {prior.dim}, task {self.task_id} needs {self.dim}")
        return dataclasses.replace(self, prior=prior)

    def describe(self) -> dict:
        """What a checkpoint or results file records about the task (JSON-ready)."""
        return {
            "task_id": self.task_id,
            "version": self.version,
            "feature_names": list(self.feature_names),
            "state_dim": self.state_dim,
            "action_dim": self.action_dim,
            "alpha": self.alpha,
            "action_bound": self.action_bound.tolist(),
            # Every other field (object positions, workspace, scales...): a checkpoint trained
            # for one geometry must not load silently for another.
            "geometry": {
                f.name: _jsonable(getattr(self, f.name))
                for f in dataclasses.fields(self)
                if f.name not in ("prior", "alpha")
            },
        }

    def network_input(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """What a learned correction term ĝ sees: (..., s), (..., a), (..., a) -> (..., k).

        Default: the state and the human action scaled by a_max. Settings whose raw state is
        not scale-free (absolute road positions, say) override this with relative quantities.
        """
        return np.concatenate([x, u_h / self.action_bound], axis=-1)

    @property
    def ghat_task(self) -> Task:
        """The Task whose shipped ĝ this Task uses (itself; a new version of a setting may use
        its predecessor's until its own are trained: same features, states and corrections)."""
        return self

    @property
    def network_input_dim(self) -> int:
        """k, the width of ``network_input``."""
        z = np.zeros
        return self.network_input(z(self.state_dim), z(self.action_dim), z(self.action_dim)).shape[
            -1
        ]

    @property
    def robot_action_bound(self) -> np.ndarray:
        """Largest |u_R| per axis; the env's action in [−1, 1] is scaled by it. Default a_max."""
        return self.action_bound

    def robot_policy(self, x: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
        """The robot's default action u_R (task units) given its estimate: (B, s), (B, d) -> (B, a).

        Default: the first step of the plan for θ̂. Settings without a planner override it.
        """
        x, theta_hat = np.atleast_2d(x), np.atleast_2d(theta_hat)
        return self.plan(theta_hat, x)[:, 1] - x

    # ----------------------------------------------------------------- planning (optional)
    def plan(self, theta: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Trajectories that maximise Σ_t R(x_t, θ) from x0: (B, d), (B, s) -> (B, T+1, s).

        A row's plan should depend on that row alone, not on the rest of the batch: ``regret``
        and the benchmark runner batch and deduplicate rows (the shipped planners do, to the
        bit; ``tests/test_planning.py`` checks it).
        """
        raise NotImplementedError(f"{type(self).__name__} has no planner")

    def regret(self, theta_hat: np.ndarray, theta_star: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Eq. S1, batched: Σ_{x∈ξ*} R(x,θ*) − Σ_{x∈ξ_θ̂} R(x,θ*), both planned from x0. -> (B,).

        Equal (θ, x0) rows are planned once: a batch of episodes that share θ* and x0 (every
        learner on one run seed) pays for θ*'s plan once.
        """
        theta_hat, theta_star, x0 = (np.atleast_2d(a) for a in (theta_hat, theta_star, x0))
        theta = np.concatenate([theta_star, theta_hat])
        starts = np.concatenate([x0, x0])
        first, inverse = unique_rows(theta, starts)
        plans = self.plan(theta[first], starts[first])[inverse]
        returns = self.reward(plans[:, 1:], np.concatenate([theta_star, theta_star])[:, None])
        total = returns.sum(axis=1)
        b = len(theta_star)
        return total[:b] - total[b:]
