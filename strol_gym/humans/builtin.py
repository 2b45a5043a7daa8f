"""The built-in human models and their single-sample adapters (``NominalHuman`` & co.).

Each model is a :class:`~strol_gym.humans.interface.HumanModel`: batched over people, its
randomness drawn by the caller's generator. Noise and bias are fractions of a_max.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from strol_gym.humans.checks import check_beta
from strol_gym.humans.choices import boltzmann_correction, driver_correction, optimal_correction
from strol_gym.humans.interface import (
    DEFAULT_CANDIDATES,
    Draws,
    HumanModel,
    Replayed,
    SimulatedHuman,
)
from strol_gym.tasks.base import Task


class NominalModel(HumanModel):
    """The eq. M6 teacher: picks the candidate correction that moves θ̂ closest to θ*, then
    adds δ ~ N(ε a_max, (σ a_max)²). It teaches relative to the robot's estimate, so it needs θ̂.

    Parameters: σ, ε (fractions of a_max), n_candidates (uniform candidates besides zero).
    """

    needs_theta_hat = True

    def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        return optimal_correction(self.task, x, u_r, theta_hat, theta_star, draws.candidates)


class BoltzmannModel(HumanModel):
    """A noisily-rational person: P(u) ∝ exp(β θ*·g(x, u, u_R)) over the candidates, then δ.
    Ignores θ̂. Parameters: σ, ε, β (rationality, 0 = uniform), n_candidates."""

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        beta: float = 50.0,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.beta = check_beta(beta)

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        return {"pick": rng.random((n, 1))}

    def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        pick = Replayed(draws.extra["pick"])
        return boltzmann_correction(
            self.task,
            x,
            u_r,
            theta_star,
            draws.candidates,
            self.beta,
            pick,
        )


class DriverModel(HumanModel):
    """A person who acts for themself, not to teach: the short-horizon θ*-maximiser of
    ``driver_correction`` over random admissible candidates, then δ. Ignores θ̂.
    Parameters: σ, ε, horizon (steps looked ahead, ≥ 1), n_candidates (default 64)."""

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        horizon: int = 4,
        n_candidates: int = 64,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        if isinstance(horizon, bool) or int(horizon) < 1:
            raise ValueError(f"horizon must be an integer >= 1, got {horizon}")
        self.horizon = int(horizon)

    def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        return driver_correction(self.task, x, u_r, theta_star, draws.candidates, self.horizon)


class ChangingModel(NominalModel):
    """The eq. M6 teacher whose preference changes mid-episode (the paper's "changing
    preferences" simulation): it teaches θ* for its first ``switch_after`` corrections, then
    ``theta_after`` (default −θ*). Parameters: σ, ε, switch_after (≥ 0), theta_after (None or
    d finite numbers), n_candidates. An env scores the episode against the final preference.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        switch_after: int = 2,
        theta_after: Any = None,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        if isinstance(switch_after, bool) or not isinstance(switch_after, int | np.integer):
            raise ValueError(f"switch_after must be an integer >= 0, got {switch_after!r}")
        if switch_after < 0:
            raise ValueError(f"switch_after must be an integer >= 0, got {switch_after!r}")
        self.switch_after = int(switch_after)
        self.theta_after: np.ndarray | None = None
        if theta_after is not None:
            after = np.asarray(theta_after, dtype=np.float64).reshape(-1)
            if after.shape != (task.dim,) or not np.isfinite(after).all():
                raise ValueError(
                    f"theta_after must be None (−θ*) or {task.dim} finite numbers, "
                    f"got {theta_after!r}"
                )
            self.theta_after = after

    def preference(self, theta_star: np.ndarray, k: np.ndarray | int) -> np.ndarray:
        after = -theta_star if self.theta_after is None else self.theta_after
        switched = np.asarray(k) >= self.switch_after
        return np.where(switched[..., None], np.broadcast_to(after, theta_star.shape), theta_star)


NominalHuman = SimulatedHuman.of(NominalModel, "NominalHuman")
BoltzmannHuman = SimulatedHuman.of(BoltzmannModel, "BoltzmannHuman")
DriverHuman = SimulatedHuman.of(DriverModel, "DriverHuman")
ChangingHuman = SimulatedHuman.of(ChangingModel, "ChangingHuman")

__all__ = [
    "BoltzmannHuman",
    "BoltzmannModel",
    "ChangingHuman",
    "ChangingModel",
    "Draws",
    "DriverHuman",
    "DriverModel",
    "NominalHuman",
    "NominalModel",
]
