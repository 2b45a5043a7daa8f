"""Simulated humans who correct the robot.

A human holds hidden weights θ* and answers ``act(x, u_R, theta_hat)`` with a correction u_H.
Real and simulated humans share this interface, so a user can pass their own object to the envs.
Noise and bias are fractions of the action bound a_max (docs/benchmark.md, "Conditions"):
δ ~ N(ε·a_max, (σ·a_max)²).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from strol_gym.registry import Registry
from strol_gym.tasks.base import Task

DEFAULT_CANDIDATES = 512


@runtime_checkable
class Human(Protocol):
    """Anything that can correct the robot. ``theta_star`` is exposed for evaluation only."""

    theta_star: np.ndarray

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
        """The correction u_H at state x, given the robot's action and current estimate."""
        ...


MAX_FRACTION = 100.0
"""The largest |σ| and |ε| accepted, in units of a_max: a correction of 100 action bounds is
already nonsense, and a bound keeps every correction (and θ̂ after it) finite."""
MAX_BETA = 1e6
"""The largest rationality β accepted: β·θ*·g must stay finite for the Boltzmann choice."""


def _number(name: str, value: Any, rng: str) -> float:
    """``value`` as a float: a number or a numeric string ("0.1", as a command line gives it);
    never a bool (``True`` is not a noise level), else ValueError naming ``name``."""
    if isinstance(value, bool | np.bool_):
        raise ValueError(f"{name} must be {rng}, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {rng}, got {value!r}") from None


def check_fraction(name: str, value: float, *, allow_negative: bool = False) -> float:
    """Validate a noise or bias level given as a fraction of a_max, |value| <= MAX_FRACTION."""
    low = -MAX_FRACTION if allow_negative else 0.0
    rng = f"a number in [{low:g}, {MAX_FRACTION:g}] (a fraction of the action bound)"
    value = _number(name, value, rng)
    if not (np.isfinite(value) and low <= value <= MAX_FRACTION):
        raise ValueError(f"{name} must be {rng}, got {value}")
    return value


def check_beta(beta: Any) -> float:
    """Validate a rationality β: a number in [0, MAX_BETA]."""
    rng = f"a number in [0, {MAX_BETA:g}]"
    value = _number("beta", beta, rng)
    if not (np.isfinite(value) and 0.0 <= value <= MAX_BETA):
        raise ValueError(f"beta must be {rng}, got {value}")
    return value


def optimal_correction(
    task: Task,
    x: np.ndarray,
    u_r: np.ndarray,
    theta_hat: np.ndarray,
    theta_star: np.ndarray,
    candidates: np.ndarray,
) -> np.ndarray:
    """Eq. M6, batched: the candidate u minimising ‖θ* − (θ̂ + α g(x, u, u_R))‖.

    Shapes: x (B, s), u_r (B, a), theta_hat / theta_star (B, d), candidates (B, K, a) -> (B, a).
    """
    g = task.g(x[:, None, :], candidates, u_r[:, None, :])  # (B, K, d)
    # θ* − (θ̂ + α g) one feature at a time, on (B, K) planes: the numbers of broadcasting
    # (B, 1, d) against (B, K, d), whose inner loops are only d long (several times slower).
    resid = np.empty_like(g)
    for j in range(g.shape[-1]):
        col = np.multiply(g[..., j], task.alpha, out=resid[..., j])
        col += theta_hat[:, j, None]
        np.subtract(theta_star[:, j, None], col, out=col)
    best = np.argmin(np.einsum("bkd,bkd->bk", resid, resid), axis=1)
    return candidates[np.arange(len(candidates)), best]


def boltzmann_correction(
    task: Task,
    x: np.ndarray,
    u_r: np.ndarray,
    theta_star: np.ndarray,
    candidates: np.ndarray,
    beta: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """A Boltzmann-rational choice among candidates: P(u) ∝ exp(β θ*·g(x, u, u_R)). (B, a)."""
    g = task.g(x[:, None, :], candidates, u_r[:, None, :])
    logits = beta * np.einsum("bkd,bd->bk", g, theta_star)
    logits -= logits.max(axis=1, keepdims=True)
    p = np.exp(logits)
    p /= p.sum(axis=1, keepdims=True)
    u = rng.random((len(p), 1))
    idx = np.minimum((p.cumsum(axis=1) < u).sum(axis=1), p.shape[1] - 1)
    return candidates[np.arange(len(candidates)), idx]


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


def perturb(
    task: Task, u: np.ndarray, sigma: float, bias: float, rng: np.random.Generator
) -> np.ndarray:
    """u + δ with δ ~ N(ε·a_max, (σ·a_max)²) per component. Draws even when σ = 0 (pairing)."""
    a = task.action_bound
    return u + bias * a + sigma * a * rng.standard_normal(u.shape)


class SimulatedHuman:
    """Shared machinery of the simulated humans: each step it draws fresh candidate actions,
    picks one with ``choose`` and adds δ. Subclasses differ only in ``choose``.

    The number of random draws per step does not depend on θ̂, so learners given one seed see
    the same candidates and noise (paired runs).
    """

    def __init__(
        self,
        task: Task,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        sigma: float = 0.0,
        bias: float = 0.0,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        self.task = task
        self.theta_star = np.asarray(theta_star, dtype=np.float64)
        self.rng = rng
        self.sigma = check_fraction("sigma", sigma)
        self.bias = check_fraction("bias", bias, allow_negative=True)
        if int(n_candidates) < 1:
            raise ValueError(f"n_candidates must be >= 1, got {n_candidates}")
        self.n_candidates = int(n_candidates)

    def choose(
        self, x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray, candidates: np.ndarray
    ) -> np.ndarray:
        """The noise-free action among ``candidates`` (1, K, a) for a batch of one: (1, a)."""
        raise NotImplementedError

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
        cand = self.task.candidate_actions(self.rng, 1, self.n_candidates)
        u = self.choose(x[None], u_r[None], theta_hat[None], cand)
        return perturb(self.task, u, self.sigma, self.bias, self.rng)[0]


class NominalHuman(SimulatedHuman):
    """The eq. M6 teacher: picks the correction that moves θ̂ closest to θ*, then adds δ.

    It needs the robot's current estimate θ̂; the env passes it (see ``set_theta_hat``).
    """

    def choose(self, x, u_r, theta_hat, candidates):
        return optimal_correction(self.task, x, u_r, theta_hat, self.theta_star[None], candidates)

    @staticmethod
    def batch_choice(task, x, u_r, theta_hat, theta_star, candidates, rng, *, beta=50.0):
        """``choose`` for a batch of humans with their own θ* (training's synthetic data)."""
        return optimal_correction(task, x, u_r, theta_hat, theta_star, candidates)


class BoltzmannHuman(SimulatedHuman):
    """A noisily-rational human: P(u) ∝ exp(β θ*·g(x, u, u_R)). Ignores θ̂; δ is added on top."""

    def __init__(
        self,
        task: Task,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        sigma: float = 0.0,
        bias: float = 0.0,
        beta: float = 50.0,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, theta_star, rng, sigma, bias, n_candidates)
        self.beta = check_beta(beta)

    def choose(self, x, u_r, theta_hat, candidates):
        th = self.theta_star[None]
        return boltzmann_correction(self.task, x, u_r, th, candidates, self.beta, self.rng)

    @staticmethod
    def batch_choice(task, x, u_r, theta_hat, theta_star, candidates, rng, *, beta=50.0):
        """``choose`` for a batch of humans with their own θ* (training's synthetic data)."""
        return boltzmann_correction(task, x, u_r, theta_star, candidates, beta, rng)


class DriverHuman(SimulatedHuman):
    """A human who acts for itself (not to teach): the short-horizon θ*-maximiser of
    ``driver_correction`` over random admissible candidates, then δ. Ignores θ̂."""

    def __init__(
        self,
        task: Task,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        sigma: float = 0.0,
        bias: float = 0.0,
        horizon: int = 4,
        n_candidates: int = 64,
    ) -> None:
        super().__init__(task, theta_star, rng, sigma, bias, n_candidates)
        if int(horizon) < 1:
            raise ValueError(f"horizon must be an integer >= 1, got {horizon}")
        self.horizon = int(horizon)

    def choose(self, x, u_r, theta_hat, candidates):
        th = self.theta_star[None]
        return driver_correction(self.task, x, u_r, th, candidates, self.horizon)


class ChangingHuman(NominalHuman):
    """The eq. M6 teacher whose preference changes mid-episode (the paper's "changing
    preferences" simulation): it teaches θ* for its first ``switch_after`` corrections, then
    ``theta_after`` (default −θ*). ``theta_star`` is always the *current* preference, so an env
    scores the episode against the final one.
    """

    def __init__(
        self,
        task: Task,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        sigma: float = 0.0,
        bias: float = 0.0,
        switch_after: int = 2,
        theta_after: Any = None,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, theta_star, rng, sigma, bias, n_candidates)
        if isinstance(switch_after, bool) or not isinstance(switch_after, int | np.integer):
            raise ValueError(f"switch_after must be an integer >= 0, got {switch_after!r}")
        if switch_after < 0:
            raise ValueError(f"switch_after must be an integer >= 0, got {switch_after!r}")
        self.switch_after = int(switch_after)
        if theta_after is None:
            after = -self.theta_star
        else:
            after = np.asarray(theta_after, dtype=np.float64).reshape(-1)
            if after.shape != self.theta_star.shape or not np.isfinite(after).all():
                raise ValueError(
                    f"theta_after must be None (−θ*) or {self.theta_star.size} finite numbers, "
                    f"got {theta_after!r}"
                )
        self.theta_before = self.theta_star.copy()
        self.theta_after = after.copy()
        self.n_acts = 0

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
        if self.n_acts == self.switch_after:
            self.theta_star = self.theta_after.copy()
        self.n_acts += 1
        return super().act(x, u_r, theta_hat)


HUMAN_MODELS: dict[str, Any] = {
    "nominal": NominalHuman,
    "boltzmann": BoltzmannHuman,
    "driver": DriverHuman,
    "changing": ChangingHuman,
}
"""The built-in human models; ``register_human`` adds to it (through ``HUMANS``)."""

HumanFactory = Callable[..., Human]
SHARED_PARAMS = ("sigma", "bias", "beta")
"""What every human factory may receive from the env or the benchmark (contract: it gets only
those its signature declares)."""


def _check_factory(name: str, factory: Any) -> None:
    if not callable(factory):
        raise ValueError(
            f"human {name!r} must be a callable (task, theta_star, rng, **params) -> Human "
            f"or a 'module:attr' string, got {factory!r}"
        )


HUMANS = Registry(
    "human",
    HUMAN_MODELS,
    check=_check_factory,
    hint=" naming a factory (task, theta_star, rng, sigma=, bias=, beta=, ...) -> Human",
)


def register_human(name: str, factory: HumanFactory | str) -> None:
    """Make ``factory`` available as ``human=name`` in the envs, the benchmark and training.

    ``factory`` is called as ``factory(task, theta_star, rng, sigma=..., bias=..., beta=...,
    **human_kwargs)`` with only the keyword arguments its signature declares (all of them if
    it takes ``**kwargs``); it may be a lazy ``"module:attr"`` string.
    """
    HUMANS.register(name, factory)


def human_factory(human: str | HumanFactory) -> HumanFactory:
    """The factory for a registered name, a ``"module:attr"`` or a callable; else ValueError."""
    if isinstance(human, str):
        factory = HUMANS.get(human)
    else:
        factory = human
    _check_factory(str(human), factory)
    return factory


def _accepted(factory: HumanFactory) -> set[str] | None:
    """Keyword names ``factory`` declares; None when it takes ``**kwargs`` (or is opaque)."""
    try:
        params = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return None
    return {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}


def check_human_kwargs(human: str | HumanFactory, human_kwargs: dict[str, Any] | None) -> dict:
    """``human_kwargs`` as a dict, else ValueError: not a mapping of names the factory declares,
    or one of the shared parameters (σ, ε, β are arguments of their own)."""
    if human_kwargs is None:
        return {}
    if not isinstance(human_kwargs, dict) or not all(isinstance(k, str) for k in human_kwargs):
        raise ValueError(f"human_kwargs must be a dict of keyword arguments, got {human_kwargs!r}")
    shared = sorted(set(human_kwargs) & set(SHARED_PARAMS))
    if shared:
        raise ValueError(
            f"human_kwargs must not hold {shared}: pass them as arguments of their own"
        )
    accepted = _accepted(human_factory(human))
    unknown = [] if accepted is None else sorted(set(human_kwargs) - accepted)
    if unknown:
        raise ValueError(
            f"human_kwargs {unknown} are not parameters of human {human!r}; "
            f"it takes {sorted(accepted - {'task', 'theta_star', 'rng'})}"
        )
    return dict(human_kwargs)


def make_human(
    human: str | HumanFactory,
    task: Task,
    theta_star: np.ndarray,
    rng: np.random.Generator,
    *,
    sigma: float = 0.0,
    bias: float = 0.0,
    beta: float = 50.0,
    **human_kwargs: Any,
) -> Human:
    """Build a human: ``factory(task, theta_star, rng, **params)`` where params are σ, ε, β and
    ``human_kwargs``, restricted to those the factory's signature declares."""
    factory = human_factory(human)
    params: dict[str, Any] = {"sigma": sigma, "bias": bias, "beta": beta, **human_kwargs}
    accepted = _accepted(factory)
    if accepted is not None:
        params = {k: v for k, v in params.items() if k in accepted}
    obj = factory(task, theta_star, rng, **params)
    if not isinstance(obj, Human):
        raise ValueError(
            f"human {human!r} must return an object with act(x, u_r, theta_hat) and "
            f"theta_star, got {type(obj).__name__}"
        )
    return obj
