"""The simulated human an env builds each episode, as one validated value.

The envs, the benchmark's conditions and the vector envs all hand a human model the same
arguments (σ, ε, β and the model's own keyword arguments); :class:`HumanSpec` carries them
together and checks them once, each error naming the field and its valid range. The envs still
take the flat keyword arguments (``human=``, ``sigma=``, ``bias=``, ``beta=``,
``human_kwargs=``) and build the spec from them (:meth:`HumanSpec.from_args`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from strol_gym.humans.checks import check_beta, check_fraction
from strol_gym.humans.interface import Human
from strol_gym.humans.population import HumanMaker
from strol_gym.humans.registry import HumanFactory, check_human_kwargs, human_factory
from strol_gym.tasks.base import Task

DEFAULT_HUMAN = "nominal"
DEFAULT_BETA = 50.0


def check_shared(sigma: Any, bias: Any, beta: Any) -> tuple[float, float, float]:
    """σ and ε (fractions of a_max; ε may be negative) and β, checked; errors name each."""
    return (
        check_fraction("sigma", sigma),
        check_fraction("bias", bias, allow_negative=True),
        check_beta(beta),
    )


@dataclasses.dataclass(frozen=True)
class HumanSpec:
    """A human model and its arguments: ``name`` (a registered human, ``"module:attr"``, a
    factory ``(task, theta_star, rng, **params) -> Human``, or None for no simulated human:
    the env's corrections then come from elsewhere, such as a person at the viewer), noise
    ``sigma`` and bias ``bias`` (fractions of a_max), rationality ``beta`` and the model's own
    ``kwargs``. A factory receives only the parameters its signature declares."""

    name: str | HumanFactory | None = DEFAULT_HUMAN
    sigma: float = 0.0
    bias: float = 0.0
    beta: float = DEFAULT_BETA
    kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        name = self.name
        if name is not None and not isinstance(name, str) and not callable(name):
            raise ValueError(
                f"human must be a registered name, 'module:attr', a callable "
                f"(task, theta_star, rng, **params) -> Human or None; got {name!r}"
            )
        sigma, bias, beta = check_shared(self.sigma, self.bias, self.beta)
        if name is None:
            if self.kwargs is not None and self.kwargs != {}:
                raise ValueError(f"human_kwargs {self.kwargs!r} given without a human model")
            kwargs: dict[str, Any] = {}
        else:
            human_factory(name)  # unknown names fail here, not at the first reset
            kwargs = check_human_kwargs(name, self.kwargs)
        object.__setattr__(self, "sigma", sigma)
        object.__setattr__(self, "bias", bias)
        object.__setattr__(self, "beta", beta)
        object.__setattr__(self, "kwargs", kwargs)

    @classmethod
    def from_args(
        cls,
        human: str | HumanFactory | HumanSpec | None = DEFAULT_HUMAN,
        sigma: float = 0.0,
        bias: float = 0.0,
        beta: float = DEFAULT_BETA,
        human_kwargs: dict[str, Any] | None = None,
    ) -> HumanSpec:
        """The spec from an env's flat keyword arguments; ``human`` may be a spec already, and
        then the others must be left at their defaults (one place for each value)."""
        if isinstance(human, HumanSpec):
            given = [
                k
                for k, v, default in (
                    ("sigma", sigma, 0.0),
                    ("bias", bias, 0.0),
                    ("beta", beta, DEFAULT_BETA),
                )
                if v != default
            ] + (["human_kwargs"] if human_kwargs else [])
            if given:
                raise ValueError(f"{given} given beside human=HumanSpec(...): put them in the spec")
            return human
        return cls(human, sigma, bias, beta, {} if human_kwargs is None else human_kwargs)

    def make(self, task: Task, theta_star: np.ndarray, rng: np.random.Generator) -> Human | None:
        """The human for one episode (None when the spec has no model); an env keeps
        ``maker(task)`` instead, to build one every episode."""
        maker = self.maker(task)
        return None if maker is None else maker(theta_star, rng)

    def maker(self, task: Task) -> HumanMaker | None:
        """What builds this spec's human episode after episode: ``make`` without resolving
        the factory and its accepted arguments each time (people of one model share it)."""
        if self.name is None:
            return None
        return HumanMaker(
            self.name, task, sigma=self.sigma, bias=self.bias, beta=self.beta, **self.kwargs
        )

    def replace(self, **changes: Any) -> HumanSpec:
        """A copy with ``changes``, validated again."""
        return dataclasses.replace(self, **changes)


__all__ = ["DEFAULT_BETA", "DEFAULT_HUMAN", "HumanSpec", "check_shared"]
