"""The one teaching loop: a batch of simulated people correct a learner, the state moving by the
Task's dynamics after each correction.

The Task-level simulation (``learners.simulate``), the basin map (``analysis.basin_map``) and
anything else that teaches without an env run this loop; the envs run the same model one
correction at a time through ``SimulatedHuman.act``, and ĝ's training data ask the same model for
whole batches (``HumanModel.correct``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from strol_gym.humans.interface import HumanModel
from strol_gym.tasks.base import Task

Update = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""``update(x, u_h, u_r) -> θ̂``: one learner step on a batch (``OnlineRewardLearner.update``)."""


def teach(
    task: Task,
    model: HumanModel,
    theta_star: np.ndarray,
    theta0: np.ndarray,
    x0: np.ndarray,
    update: Update,
    rng: np.random.Generator,
    n_corrections: int,
    *,
    robot_policy: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    shared_draws: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """θ̂ and x (each (n, ·)) after ``n_corrections`` corrections of n people by ``model``.

    - ``theta_star`` (n, d) the people's preferences, ``theta0`` (n, d) the learner's start
      (the learner must already be reset to it), ``x0`` (n, s) the start states;
    - u_R is ``robot_policy(x, θ̂)``, or 0 when it is None;
    - ``shared_draws``: one draw per correction shared by every row (the same person taught
      from many θ̂0, as the basin map does), else a draw per row.
    """
    if isinstance(n_corrections, bool) or int(n_corrections) < 0:
        raise ValueError(f"n_corrections must be an integer >= 0, got {n_corrections!r}")
    n = len(theta_star)
    theta, x = np.asarray(theta0, dtype=np.float64), np.asarray(x0, dtype=np.float64)
    u_r = np.zeros((n, task.action_dim))
    for k in range(int(n_corrections)):
        if robot_policy is not None:
            u_r = np.asarray(robot_policy(x, theta), dtype=np.float64)
        draws = model.draw(rng, 1).broadcast(n) if shared_draws else model.draw(rng, n)
        u_h = model.corrections(x, u_r, theta_star, draws, theta, k)
        theta = np.atleast_2d(np.asarray(update(x, u_h, u_r), dtype=np.float64))
        x = task.dynamics(x, u_h, u_r)
    return theta, x
