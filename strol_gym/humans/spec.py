"""The simulated person an env builds each episode, as one validated value: ``person=``.

Every env takes one ``person=`` argument for every kind of person (a correcting human model,
a study participant, the fitted population):

- omitted: the env's default person;
- ``None``: no simulated person (the corrections come from elsewhere: scripted pushes, a real
  person at the viewer, or none);
- a name (a registered human, an env's own person such as the study's ``"fitted"``, or
  ``"module:attr"``), or a factory ``(task, theta_star, rng, **params) -> Human``;
- a :class:`HumanSpec` with its parameters, ``HumanSpec("boltzmann", sigma=0.35, bias=0.0)``,
  or the same as a dict (``{"name": "boltzmann", "sigma": 0.35}``; without ``"name"``: the
  env's default person with those parameters).

A spec holds only what was given: σ, ε and β are None unless set. The env then resolves it
against the person it names and refuses a parameter that person does not use, naming it
(:meth:`HumanSpec.as_used` for the human models; the study env has its own people). What it
keeps (``env.person_spec``) is the person as used: every parameter the person takes, with the
defaults filled in, and only those.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from strol_gym import checks
from strol_gym.humans.checks import check_beta, check_fraction
from strol_gym.humans.interface import Human
from strol_gym.humans.population import HumanMaker
from strol_gym.humans.registry import (
    SHARED_PARAMS,
    HumanFactory,
    _accepted,
    check_human_kwargs,
    human_factory,
)
from strol_gym.tasks.base import Task

DEFAULT_HUMAN = "nominal"
DEFAULT_BETA = 50.0
SHARED_DEFAULTS: dict[str, float] = {"sigma": 0.0, "bias": 0.0, "beta": DEFAULT_BETA}
"""What a person that takes σ, ε or β gets when the spec leaves it unset."""
PERSON_ARGUMENTS = ("human", "sigma", "bias", "beta", "human_kwargs", "participant", "user_kwargs")
"""Keywords that describe the person: an env given one as its own argument refuses it and points
to ``person=`` (the unknown-argument error)."""


_CHECKS = {  # the one check of each shared value (the envs, the benchmark's conditions)
    "sigma": lambda v: check_fraction("sigma", v),
    "bias": lambda v: check_fraction("bias", v, allow_negative=True),
    "beta": check_beta,
}


@dataclasses.dataclass(frozen=True)
class HumanSpec:
    """A person and its parameters: ``name`` (a registered human, an env's own person such as
    the study's ``"fitted"``, ``"module:attr"``, or a factory ``(task, theta_star, rng,
    **params) -> Human``), noise ``sigma`` and bias ``bias`` (fractions of a_max), rationality
    ``beta`` (None: not given, the person's default) and the person's own ``kwargs``. The
    ranges are checked here, once; whether the person uses each value, where the env resolves
    it (a factory receives only the parameters its signature declares)."""

    name: str | HumanFactory
    sigma: float | None = None
    bias: float | None = None
    beta: float | None = None
    kwargs: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        name = self.name
        if not (isinstance(name, str) and name) and (isinstance(name, str) or not callable(name)):
            raise ValueError(
                f"person must be a registered name, 'module:attr', a callable "
                f"(task, theta_star, rng, **params) -> Human or None; got {name!r}"
            )
        for key, check in _CHECKS.items():
            value = getattr(self, key)
            if value is not None:
                object.__setattr__(self, key, check(value))
        kwargs = checks.mapping("kwargs", self.kwargs)
        shared = sorted(set(kwargs) & set(SHARED_PARAMS))
        if shared:
            raise ValueError(
                f"kwargs must not hold {shared}: they are HumanSpec fields of their own"
            )
        object.__setattr__(self, "kwargs", kwargs)

    def given(self) -> dict[str, float]:
        """σ, ε and β as set (the unset ones left out)."""
        return {k: v for k in SHARED_PARAMS if (v := getattr(self, k)) is not None}

    def refuse(self, unused: set[str] | list[str], takes: list[str] | set[str]) -> None:
        """ValueError naming the first of ``unused`` that was set (σ, ε, β), if any."""
        given = [k for k in SHARED_PARAMS if k in unused and getattr(self, k) is not None]
        if given:
            raise ValueError(
                f"{given[0]} is not a parameter of person {self.label()!r} "
                f"(given {given[0]}={getattr(self, given[0])!r}); it takes {sorted(takes)}"
            )

    def label(self) -> str:
        """The name as text: a factory by its ``module:qualname``."""
        name = self.name
        if isinstance(name, str):
            return name
        return f"{getattr(name, '__module__', '?')}:{getattr(name, '__qualname__', repr(name))}"

    def as_used(self) -> HumanSpec:
        """This spec resolved against the human models' registry: the person as the env uses
        it (each parameter it takes, defaults filled in; None for those it does not take).
        ValueError naming the name when it is not a human, or a set σ, ε, β or ``kwargs`` key
        the person does not use."""
        factory = human_factory(self.name)  # unknown names fail here, not at the first reset
        accepted = _accepted(factory)
        takes = set(SHARED_PARAMS) if accepted is None else set(accepted) & set(SHARED_PARAMS)
        own = self.kwargs_taken(accepted)
        self.refuse(set(SHARED_PARAMS) - takes, takes | set(own))
        unknown = [] if accepted is None else sorted(set(self.kwargs) - set(own))
        if unknown:
            raise ValueError(
                f"person kwargs {unknown} are not parameters of person {self.label()!r}; "
                f"it takes {own}"
            )
        kwargs = check_human_kwargs(self.name, dict(self.kwargs))
        given = self.given()

        def used(k: str) -> float | None:
            return given.get(k, SHARED_DEFAULTS[k]) if k in takes else None

        return HumanSpec(self.name, used("sigma"), used("bias"), used("beta"), kwargs)

    @staticmethod
    def kwargs_taken(accepted: set[str] | None) -> list[str]:
        """The model's own keyword arguments among ``accepted`` (its signature's names)."""
        if accepted is None:
            return []
        return sorted(accepted - set(SHARED_PARAMS) - {"task", "theta_star", "rng"})

    def params(self) -> dict[str, Any]:
        """What the person's factory is called with: σ, ε, β as set, then ``kwargs``."""
        return {**self.given(), **self.kwargs}

    def make(self, task: Task, theta_star: np.ndarray, rng: np.random.Generator) -> Human:
        """The human for one episode; an env keeps ``maker(task)`` instead, to build one
        every episode."""
        return self.maker(task)(theta_star, rng)

    def maker(self, task: Task) -> HumanMaker:
        """What builds this spec's human episode after episode: ``make`` without resolving
        the factory and its accepted arguments each time (people of one model share it)."""
        return HumanMaker(self.name, task, **self.params())

    def replace(self, **changes: Any) -> HumanSpec:
        """A copy with ``changes``, validated again."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """JSON form: the name (a factory as ``module:qualname``), the parameters set, and
        ``kwargs`` when there are any."""
        d: dict[str, Any] = {"name": self.label(), **self.given()}
        if self.kwargs:
            d["kwargs"] = dict(self.kwargs)
        return d


class _Omitted:
    """The type of :data:`DEFAULT_PERSON`."""

    def __repr__(self) -> str:
        return "DEFAULT_PERSON"


DEFAULT_PERSON: Any = _Omitted()
"""``person=`` omitted: the env's default person."""

Person = HumanSpec | str | Mapping[str, Any] | HumanFactory | None
"""What ``person=`` takes (see the module docstring)."""


def person_spec(person: Any, default: str | HumanFactory) -> HumanSpec | None:
    """The ``person=`` argument as a spec, ``default`` naming the env's default person:
    omitted -> ``HumanSpec(default)``, None -> None, a name or factory, a spec, or a dict of
    the spec's fields (``name`` defaulting to ``default``). ValueError naming ``person``."""
    if person is DEFAULT_PERSON:
        return HumanSpec(default)
    if person is None or isinstance(person, HumanSpec):
        return person
    if isinstance(person, str) or (callable(person) and not isinstance(person, Mapping)):
        return HumanSpec(person)
    if isinstance(person, Mapping):
        fields = {f.name for f in dataclasses.fields(HumanSpec)}
        unknown = sorted(set(map(str, person)) - fields)
        if unknown:
            raise ValueError(
                f"person {unknown} are not fields of a person; it takes {sorted(fields)} "
                "(the person's own parameters go in 'kwargs')"
            )
        return HumanSpec(**{"name": default, **person})
    raise ValueError(
        "person must be omitted (the env's default), None (no simulated person), a name, "
        f"a HumanSpec or a dict of its fields; got {person!r}"
    )


__all__ = [
    "DEFAULT_BETA",
    "DEFAULT_HUMAN",
    "DEFAULT_PERSON",
    "PERSON_ARGUMENTS",
    "SHARED_DEFAULTS",
    "HumanSpec",
    "Person",
    "person_spec",
]
