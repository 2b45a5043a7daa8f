"""Analysis of the learning dynamics themselves: the basin of attraction (paper, eq. M5, Fig. 2).

``basin_map`` asks, for every θ̂0 on a grid over a 2-D slice of the parameter space (the other
coordinates fixed), where the learning dynamics θ̂ ← θ̂ + α·G(x, u_H, u_R) end after a few
corrections by one fixed, seeded human. Every cell sees the same human draws (candidate
actions, noise, start state), so the map shows the learning rule, not luck. The whole grid is
one batch: the human, the kinematics and the learner all run vectorised over the cells.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from strol_gym.humans import DEFAULT_CANDIDATES, check_fraction, human_model, teach
from strol_gym.priors import check_theta_range
from strol_gym.tasks.base import Task

CONVERGED_TOL = 0.25
"""A cell *converges* when its final error ‖θ̂_K − θ*‖ is at most ``CONVERGED_TOL · ‖θ*‖``
(a quarter of the preference's length: the estimate ends in θ*'s neighbourhood)."""


@dataclasses.dataclass(frozen=True)
class BasinMap:
    """Final error per cell: ``error[i, j]`` is for θ̂0 with coordinate ``dims[0]`` =
    ``axis0[j]`` and ``dims[1]`` = ``axis1[i]`` (rows follow the second axis, as an image)."""

    axis0: np.ndarray
    axis1: np.ndarray
    dims: tuple[int, int]
    theta_star: np.ndarray
    error: np.ndarray
    tol: float = CONVERGED_TOL

    @property
    def converged(self) -> np.ndarray:
        """Boolean map: final error ≤ tol · ‖θ*‖."""
        return self.error <= self.tol * float(np.linalg.norm(self.theta_star))

    @property
    def fraction_converged(self) -> float:
        return float(self.converged.mean())


def _grid_axis(name: str, value: Any, span: tuple[float, float]) -> np.ndarray:
    if isinstance(value, int | np.integer) and not isinstance(value, bool):
        if value < 2:  # one point would ignore span: pass [value] for a single cell
            raise ValueError(f"{name} must be an integer >= 2 or a sequence of values, got {value}")
        return np.linspace(span[0], span[1], int(value))
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.size == 0 or not np.isfinite(arr).all():
        raise ValueError(f"{name} must be an integer >= 1 or finite values, got {value!r}")
    return arr


def basin_map(
    task: Task,
    learner: Any,
    grid: int | Sequence[float] | tuple[Any, Any] = 41,
    *,
    theta_star: Sequence[float] | None = None,
    dims: tuple[int, int] = (0, 1),
    span: tuple[float, float] = (-1.5, 1.5),
    fixed: Sequence[float] | None = None,
    steps: int = 10,
    sigma: float = 0.25,
    bias: float = 0.0,
    seed: int = 0,
    n_candidates: int = DEFAULT_CANDIDATES,
    tol: float = CONVERGED_TOL,
) -> BasinMap:
    """The final error of ``learner`` from every θ̂0 of a grid, taught by one seeded human.

    - ``learner``: a registered name or ``"module:attr"`` (built for ``task``) or a learner
      object whose ``reset``/``update`` take batches.
    - ``grid``: points per axis (int ≥ 2), one sequence of values for both axes, or a pair
      (values for ``dims[0]``, values for ``dims[1]``); ints span ``span``.
    - ``theta_star``: the human's preference (default: the task's first prior mode).
    - ``fixed``: θ̂0's other coordinates (default: those of the prior modes' mean).
    - The human is the eq. M6 teacher (``NominalHuman``) with noise σ and bias ε (fractions of
      a_max); the robot holds still (u_R = 0), so only the human's corrections move x and θ̂.
      Start state, candidates and noise come from ``numpy.random.default_rng(seed)`` and are
      shared by every cell.
    """
    from strol_gym.learners.registry import make_learner

    d = task.dim
    if d < 2:
        raise ValueError(f"basin_map needs a task with at least 2 parameters, got dim {d}")
    i0, i1 = (int(k) for k in dims)
    if not (0 <= i0 < d and 0 <= i1 < d and i0 != i1):
        raise ValueError(f"dims must be two different indices in [0, {d - 1}], got {dims}")
    if int(steps) < 1:
        raise ValueError(f"steps must be an integer >= 1, got {steps}")
    sigma = check_fraction("sigma", sigma)
    bias = check_fraction("bias", bias, allow_negative=True)
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a finite number > 0, got {tol}")
    if isinstance(grid, tuple) and len(grid) == 2:
        ax0, ax1 = _grid_axis("grid[0]", grid[0], span), _grid_axis("grid[1]", grid[1], span)
    else:
        ax0 = ax1 = _grid_axis("grid", grid, span)
    modes = np.asarray(task.prior_modes, dtype=np.float64)
    star = modes[0].copy() if theta_star is None else np.asarray(theta_star, dtype=np.float64)
    if star.shape != (d,):
        raise ValueError(f"theta_star must be {d} numbers, got {theta_star!r}")
    check_theta_range("theta_star", star)
    base = modes.mean(axis=0) if fixed is None else np.asarray(fixed, dtype=np.float64)
    if base.shape != (d,) or not np.isfinite(base).all():
        raise ValueError(f"fixed must be {d} finite numbers (all coordinates), got {fixed!r}")

    g0, g1 = np.meshgrid(ax0, ax1)  # (n1, n0)
    theta0 = np.tile(base, (g0.size, 1))
    theta0[:, i0], theta0[:, i1] = g0.ravel(), g1.ravel()
    b = len(theta0)

    learner = make_learner(learner, task=task) if isinstance(learner, str) else learner
    learner.reset(theta0)
    rng = np.random.default_rng(seed)
    x = np.repeat(task.sample_start(rng, 1), b, axis=0)
    teacher = human_model("nominal", task, sigma=sigma, bias=bias, n_candidates=int(n_candidates))
    stars = np.broadcast_to(star, (b, d))
    teach(task, teacher, stars, theta0, x, learner.update, rng, int(steps), shared_draws=True)
    final = np.atleast_2d(np.asarray(learner.theta, dtype=np.float64))
    err = np.linalg.norm(final - star, axis=1).reshape(g0.shape)
    if not np.isfinite(err).all():  # θ̂ itself is checked by every update; its error too
        raise ValueError("the final errors overflow: theta_star or the grid is too large")
    return BasinMap(ax0, ax1, (i0, i1), star, err, float(tol))
