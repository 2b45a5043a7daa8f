"""What every strol-gym env shares: the corrective human, θ̂, argument checks, action and info.

Both envs (MuJoCo arm, highway-env cars) are a Task plus a simulator. This mixin holds the part
that is the same whatever simulates the Task, so the two envs agree on the contract the
learners, the wrapper and the benchmark rely on (see the env docstrings).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from strol_gym.humans import HUMAN_MODELS, Human, check_fraction
from strol_gym.priors import Prior, make_prior
from strol_gym.tasks.base import Task

HumanFactory = Callable[[Task, np.ndarray, np.random.Generator], Human]
RESET_OPTIONS = ("theta_star", "state")


def int_arg(name: str, value: Any, low: int, high: int | None = None) -> int:
    """An integer argument in [low, high], else ValueError naming it and the range."""
    ok = isinstance(value, int | np.integer) and not isinstance(value, bool)
    if ok and value >= low and (high is None or value <= high):
        return int(value)
    rng = f">= {low}" if high is None else f"in [{low}, {high}]"
    raise ValueError(f"{name} must be an integer {rng}, got {value!r}")


def vector_arg(name: str, value: Any, n: int) -> np.ndarray:
    """``n`` finite numbers as a fresh float64 vector, else ValueError naming the argument."""
    v = np.asarray(value, dtype=np.float64).reshape(-1)
    if v.shape != (n,) or not np.isfinite(v).all():
        raise ValueError(f"{name} must be {n} finite numbers, got {value!r}")
    return v.copy()


class CorrectionEnvMixin:
    """The human-correction half of a strol-gym env. Mixed in before the simulator's base class.

    The env calls ``_configure`` in ``__init__``; then ``set_theta_hat``, ``_make_human``,
    ``_reset_overrides``, ``_robot_action`` and ``_info`` give every env the same behaviour.
    """

    KWARGS: tuple[str, ...] = (
        "sigma",
        "bias",
        "prior",
        "human",
        "beta",
        "n_corrections",
        "max_episode_steps",
        "render_mode",
        "width",
        "height",
        "task",
    )
    metadata: dict[str, Any]
    task: Any
    theta_star: np.ndarray
    theta_hat: np.ndarray

    def _configure(
        self,
        env_id: str,
        task: Task | None,
        task_cls: type[Task],
        unknown: dict[str, Any],
        *,
        sigma: float,
        bias: float,
        prior: str | Prior | Any,
        human: str | HumanFactory,
        beta: float,
        n_corrections: int,
        render_mode: str | None,
    ) -> None:
        """Validate the shared keyword arguments; each error names the argument and its range."""
        if unknown:
            raise ValueError(f"unknown argument(s) {sorted(unknown)}; {env_id} takes {self.KWARGS}")
        if task is None:
            task = task_cls()
        elif not isinstance(task, task_cls):
            raise ValueError(
                f"task must be a {task_cls.__name__} or None, got {type(task).__name__}"
            )
        self.task = task.with_prior(make_prior(prior, task.prior_modes))
        self.sigma = check_fraction("sigma", sigma)
        self.bias = check_fraction("bias", bias, allow_negative=True)
        if not (isinstance(human, str) and human in HUMAN_MODELS) and not (
            callable(human) and not isinstance(human, str)
        ):
            raise ValueError(
                f"human must be one of {sorted(HUMAN_MODELS)} or a callable "
                f"(task, theta_star, rng) -> Human; got {human!r}"
            )
        self.human_model = human
        beta = float(beta)
        if not (np.isfinite(beta) and beta >= 0):
            raise ValueError(f"beta must be a finite number >= 0, got {beta}")
        self.beta = beta
        self.n_corrections = int_arg("n_corrections", n_corrections, 0)
        modes = self.metadata["render_modes"]
        if render_mode is not None and render_mode not in modes:
            raise ValueError(f"render_mode must be None or one of {modes}, got {render_mode!r}")
        self._u_scale = np.asarray(self.task.robot_action_bound, dtype=np.float64)
        self.theta_hat = self._default_theta_hat()

    # ------------------------------------------------------------------ θ̂ and the human
    def _default_theta_hat(self) -> np.ndarray:
        return np.asarray(self.task.prior_modes, dtype=np.float64).mean(axis=0)

    def set_theta_hat(self, theta_hat: np.ndarray) -> None:
        """The robot's current estimate θ̂: the nominal human teaches relative to it, and the
        next observation carries it. Reset restores the bimodal prior modes' mean."""
        th = np.asarray(theta_hat, dtype=np.float64).reshape(-1)
        if th.shape != (self.task.dim,) or not np.isfinite(th).all():
            raise ValueError(f"theta_hat must be {self.task.dim} finite numbers, got {theta_hat}")
        self.theta_hat = th.copy()

    def _make_human(self, theta_star: np.ndarray, rng: np.random.Generator) -> Human:
        if isinstance(self.human_model, str):
            cls = HUMAN_MODELS[self.human_model]
            kw: dict[str, Any] = {"sigma": self.sigma, "bias": self.bias}
            if self.human_model == "boltzmann":
                kw["beta"] = self.beta
            return cls(self.task, theta_star, rng, **kw)
        human = self.human_model(self.task, theta_star, rng)
        if not isinstance(human, Human):
            raise ValueError(
                "human callable must return an object with act(x, u_r, theta_hat) and "
                f"theta_star, got {type(human).__name__}"
            )
        return human

    def _reset_overrides(self, options: dict | None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """``reset(options={"theta_star": ..., "state": ...})``: checked overrides or None."""
        options = dict(options or {})
        bad = set(options) - set(RESET_OPTIONS)
        if bad:
            raise ValueError(f"unknown reset option(s) {sorted(bad)}; valid: {RESET_OPTIONS}")
        theta_star = options.get("theta_star")
        state = options.get("state")
        return (
            None if theta_star is None else vector_arg("theta_star", theta_star, self.task.dim),
            None if state is None else vector_arg("state", state, self.task.state_dim),
        )

    # ------------------------------------------------------------------ step helpers
    def _robot_action(self, action: Any) -> np.ndarray:
        """The action in [−1, 1] as u_R in task units. Out of range clips; NaN/inf raises."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (self.task.action_dim,):
            raise ValueError(
                f"action must have shape ({self.task.action_dim},), got {np.shape(action)}"
            )
        if not np.isfinite(a).all():
            raise ValueError(f"action must be finite, got {action}")
        return np.minimum(np.maximum(a, -1.0), 1.0) * self._u_scale

    def _info(
        self, phi: np.ndarray, u_h: np.ndarray, u_r: np.ndarray, is_correction: bool
    ) -> dict[str, Any]:
        """The info keys every strol-gym env provides; envs add their own on top."""
        return {
            "features": dict(zip(self.task.feature_names, phi.tolist(), strict=True)),
            "phi": phi,
            "correction": np.array(u_h, dtype=np.float64),
            "robot_action": np.array(u_r, dtype=np.float64),
            "theta_star": self.theta_star.copy(),
            "theta_hat": self.theta_hat.copy(),
            "is_correction": bool(is_correction),
        }
