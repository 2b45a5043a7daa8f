"""The paper's evaluation conditions (Fig. 4 columns) and the per-env presets.

A :class:`Condition` is everything about the simulated human that the benchmark varies: noise σ
and bias ε (fractions of a_max, DESIGN.md), the prior θ* is drawn from, and the human model.
The robot's initial estimate θ̂0 is *not* part of a condition: in every condition it is the mean
of the designer's bimodal prior modes (``task.prior_modes.mean(0)``), which is what the envs and
learners use by default. The uniform-prior condition changes only where θ* comes from.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from strol_gym.humans import HUMAN_MODELS

PAPER_LEARNERS: tuple[str, ...] = ("gradient", "one", "mof", "e2e", "strol")
"""The paper's five rules, in the order its figures use."""

REFERENCE_LEARNER = "strol"
"""The learner every post-hoc test compares against the others."""

PRIORS = ("bimodal", "uniform")
HUMANS: tuple[str, ...] = tuple(HUMAN_MODELS)
"""Human model names the envs accept; a condition's ``None`` means the env's own default."""
CONDITION_NAMES = ("training", "clean", "noisy-biased", "uniform-prior")


@dataclasses.dataclass(frozen=True)
class Condition:
    """A simulated-human setting: σ, ε (fractions of a_max), prior, human model (and its β).

    ``human=None`` leaves the env's default human model (the eq. M6 teacher for the Robot).
    """

    name: str
    sigma: float
    bias: float = 0.0
    prior: str = "bimodal"
    human: str | None = None
    beta: float | None = None

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise ValueError(f"condition name must be a non-empty string, got {self.name!r}")
        if not (math.isfinite(self.sigma) and self.sigma >= 0):
            raise ValueError(f"sigma (noise) must be a finite number >= 0, got {self.sigma}")
        if not math.isfinite(self.bias):
            raise ValueError(f"bias must be a finite number, got {self.bias}")
        if self.prior not in PRIORS:
            raise ValueError(f"prior must be one of {PRIORS}, got {self.prior!r}")
        if self.human is not None and self.human not in HUMANS:
            raise ValueError(f"human must be one of {HUMANS}, got {self.human!r}")
        if self.beta is not None and not (math.isfinite(self.beta) and self.beta >= 0):
            raise ValueError(f"beta must be a finite number >= 0, got {self.beta}")
        if self.beta is not None and self.human != "boltzmann":
            raise ValueError("beta only applies to human='boltzmann'")

    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for ``gymnasium.make`` (the env contract in CONVENTIONS.md)."""
        kw: dict[str, Any] = {"sigma": self.sigma, "bias": self.bias, "prior": self.prior}
        if self.human is not None:
            kw["human"] = self.human
        if self.beta is not None:
            kw["beta"] = self.beta
        return kw

    def describe(self) -> str:
        """One line for tables: σ, ε, prior, human."""
        h = self.human or "env-default"
        h = h if self.beta is None else f"{h} (β={self.beta:g})"
        return f"σ={self.sigma:g}, ε={self.bias:g}, {self.prior} prior, {h} human"


@dataclasses.dataclass(frozen=True)
class EnvPreset:
    """What the paper fixes per environment: id, run count, correction steps, primary metric."""

    key: str
    env_id: str
    runs: int
    n_corrections: int
    training_sigma: float
    primary_metric: str

    def conditions(self) -> dict[str, Condition]:
        """The paper's four conditions for this env (DESIGN.md's table), in figure order."""
        s = self.training_sigma
        return {
            "training": Condition("training", sigma=s, bias=0.0, prior="bimodal"),
            "clean": Condition("clean", sigma=0.0, bias=0.0, prior="bimodal"),
            "noisy-biased": Condition("noisy-biased", sigma=0.5, bias=0.5, prior="bimodal"),
            "uniform-prior": Condition("uniform-prior", sigma=s, bias=0.0, prior="uniform"),
        }


ENV_PRESETS: dict[str, EnvPreset] = {
    "robot": EnvPreset(
        key="robot",
        env_id="StROL-Robot-v0",
        runs=100,
        n_corrections=5,
        training_sigma=0.25,
        primary_metric="regret",
    ),
    "highway": EnvPreset(
        key="highway",
        env_id="StROL-Highway-v0",
        runs=250,
        n_corrections=10,
        training_sigma=0.10,
        primary_metric="error",
    ),
}


def env_preset(key: str) -> EnvPreset:
    """The preset for ``key`` ("robot" | "highway"); ValueError listing the valid keys."""
    try:
        return ENV_PRESETS[key]
    except KeyError:
        raise ValueError(f"env must be one of {sorted(ENV_PRESETS)}, got {key!r}") from None


def paper_condition(env: str, name: str) -> Condition:
    """One of the paper's conditions for ``env``; ValueError listing the valid names."""
    conds = env_preset(env).conditions()
    if name not in conds:
        raise ValueError(f"condition must be one of {list(conds)}, got {name!r}")
    return conds[name]


def custom_condition(
    env: str,
    *,
    name: str = "custom",
    sigma: float | None = None,
    bias: float = 0.0,
    prior: str = "bimodal",
    human: str | None = None,
    beta: float | None = None,
) -> Condition:
    """An explicit condition; σ defaults to the env's training noise."""
    preset = env_preset(env)
    return Condition(
        name=name,
        sigma=preset.training_sigma if sigma is None else float(sigma),
        bias=float(bias),
        prior=prior,
        human=human,
        beta=beta,
    )
