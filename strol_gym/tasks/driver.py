"""A short-horizon driver's choice, batched: what a car does for itself under reward weights θ.

It needs only a Task's ``dynamics`` and ``features``, so it lives beside the Tasks: the highway
Task's robot policy predicts the human car with it, and the ``driver`` human model
(``strol_gym.humans``) chooses with it. Keeping it here, below ``humans``, is what lets the Task
import it at module level without an import cycle (``tests/test_layers.py``).
"""

from __future__ import annotations

import numpy as np

from strol_gym.tasks.base import Task


def driver_correction(
    task: Task,
    x: np.ndarray,
    u_r: np.ndarray,
    theta_star: np.ndarray,
    candidates: np.ndarray,
    horizon: int,
) -> np.ndarray:
    """A short-horizon driver, batched: the candidate u maximising Σ_{t=1..horizon} θ*·φ(x_t)
    when u (and the robot's u_R) act for the first step and both coast (zero action) after it.
    Acting for itself, not to teach: it ignores θ̂. Coasting, rather than repeating u, lets a
    car value "steer now, then hold the wheel" without the plan turning it around.

    Shapes: x (B, s), u_r (B, a), theta_star (B, d), candidates (B, K, a) -> (B, a).
    """
    if int(horizon) < 1:
        raise ValueError(f"horizon must be an integer >= 1, got {horizon}")
    xs = task.dynamics(x[:, None, :], candidates, u_r[:, None, :])
    total = np.einsum("bkd,bd->bk", task.features(xs), theta_star)
    zero = np.zeros((1, 1, candidates.shape[-1]))
    for _ in range(int(horizon) - 1):
        xs = task.dynamics(xs, zero, zero)
        total += np.einsum("bkd,bd->bk", task.features(xs), theta_star)
    return candidates[np.arange(len(candidates)), np.argmax(total, axis=1)]
