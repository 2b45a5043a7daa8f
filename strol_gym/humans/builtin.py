"""The built-in human models and their single-sample adapters (``NominalHuman`` & co.).

Each model is a :class:`~strol_gym.humans.interface.HumanModel`: batched over people, its
randomness drawn by the caller's generator. Noise and bias are fractions of a_max.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from strol_gym.compiled import use_fast
from strol_gym.draws import uniform_rows
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

    def drawn_corrections(self, rngs, x, u_r, theta_star, theta_hat=None, k=0):
        """The Task's compiled correction from the draws (``Task.m6_drawn``), where the model
        and its Task are the ones it repeats; person b's uniform candidates and noise are drawn
        from ``rngs[b]`` as ``draw_each`` draws them, a chunk of people at a time (their
        candidates stay in the cache instead of one (B, K, a) array)."""
        drawn = _drawn_as_nominal(self) if use_fast() and theta_hat is not None else None
        if drawn is None:
            return None
        n, a = len(rngs), self.task.action_dim
        c, f64 = np.ascontiguousarray, np.float64
        x, u_r, theta_hat = c(x, dtype=f64), c(u_r, dtype=f64), c(theta_hat, dtype=f64)
        pref = c(self.preference(theta_star, k), dtype=f64)
        out = np.empty((n, a))
        if n == 1:  # one person (a single env's every correction): no chunks
            rng = rngs[0]
            units = rng.random((1, self.n_candidates, a))  # the same draws as ``out=`` a block
            noise = rng.standard_normal((1, a))
            drawn(x, u_r, theta_hat, pref, units, noise, self.sigma, self.bias, out)
            return out
        units = np.empty((DRAWN_CHUNK, self.n_candidates, a))
        noise = np.empty((n, a))
        for lo in range(0, n, DRAWN_CHUNK):
            hi = min(lo + DRAWN_CHUNK, n)
            # each generator's uniforms (one compiled call for them all), then its normals
            uniform_rows(rngs[lo:hi], units[: hi - lo].reshape(hi - lo, -1))
            for rng, z in zip(rngs[lo:hi], noise[lo:hi], strict=True):
                rng.standard_normal(out=z)
            p = slice(lo, hi)
            drawn(
                x[p], u_r[p], theta_hat[p], pref[p], units[: hi - lo], noise[p], self.sigma,
                self.bias, out[p],
            )  # fmt: skip
        return out


DRAWN_CHUNK = 32
"""People per call of ``Task.m6_drawn`` in ``NominalModel.drawn_corrections``."""


_NOMINAL = ("draw", "draw_each", "draw_extra", "corrections", "choose")


def _drawn_as_nominal(model: NominalModel) -> Callable[..., None] | None:
    """Its Task's ``m6_drawn`` where ``model`` draws, chooses and perturbs as ``NominalModel``
    does, with one σ and ε; else None."""
    own = type(model)
    same = _AS_NOMINAL.get(own)
    if same is None:
        same = _AS_NOMINAL[own] = all(getattr(own, n) is getattr(NominalModel, n) for n in _NOMINAL)
    if not same or type(model.sigma) is not float or type(model.bias) is not float:
        return None
    return model.task.m6_drawn()


_AS_NOMINAL: dict[type, bool] = {}


def drawn_teacher(human: Any, task: Task) -> NominalModel | None:
    """The model of ``human`` where an env may compute one correction straight from the
    person's draws, as ``SimulatedHuman.act`` would through ``drawn_corrections``: a
    ``SimulatedHuman`` (its ``act`` and ``begin`` the adapter's own) of an eq. M6 teacher on
    ``task`` whose compiled path runs (``_drawn_as_nominal``); else None."""
    model = getattr(human, "model", None)
    if (
        not isinstance(human, SimulatedHuman)
        or type(human).act is not SimulatedHuman.act
        or type(human).begin is not SimulatedHuman.begin
        or not isinstance(model, NominalModel)
        or type(model).drawn_corrections is not NominalModel.drawn_corrections
        or not model.needs_theta_hat
        or model.task is not task
        or not use_fast()
        or _drawn_as_nominal(model) is None
    ):
        return None
    return model


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
    "drawn_teacher",
]
