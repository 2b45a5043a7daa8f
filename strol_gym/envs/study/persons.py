"""The study's simulated people by the names ``person=`` gives them: what each uses and builds.

- ``"fitted"`` (v2's default): a person drawn from the population fitted to the authors'
  twelve participants (``participant.FittedParticipant``); its noise is fitted, so it takes no
  σ, ε or β; ``kwargs`` override the drawn ``FittedParams`` fields.
- ``"observer"`` (v1's default): the participant who judges the cup's motion
  (``participant.Participant``): σ and ε (its hand's noise and bias), ``kwargs`` the
  ``ParticipantParams`` fields.
- ``"oracle"`` (v0's, the only one v0 has) or the name of a human model: v0's regret-judging
  ``user.SimulatedUser``, pushing what that model wants ("oracle": "nominal", eq. M6): σ, ε
  and β as the model takes them; ``kwargs`` the model's own and the ``PushParams`` fields.

Each resolves a :class:`~strol_gym.humans.spec.HumanSpec` to the person as used (defaults
filled in) and refuses, naming it, a parameter the person does not use.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Protocol, runtime_checkable

import numpy as np

from strol_gym.envs.study import population
from strol_gym.envs.study.participant import FittedParticipant, Participant
from strol_gym.envs.study.people import FittedParams, ParticipantParams, Pusher, PushParams
from strol_gym.envs.study.user import SimulatedUser
from strol_gym.humans.spec import SHARED_DEFAULTS, HumanSpec
from strol_gym.tasks.study import StudyTask

ORACLE = "oracle"
ORACLE_MODEL = "nominal"
"""The human model of the ``"oracle"`` person (eq. M6, the training human)."""


@runtime_checkable
class StudyPerson(Pusher, Protocol):
    """A simulated person of the study: pushes the hand (``people.Pusher``) and wants θ*."""

    @property
    def theta_star(self) -> np.ndarray:
        """Its current preference θ* (what the env's reward uses)."""
        ...


def _names(cls: type) -> set[str]:
    return {f.name for f in dataclasses.fields(cls)}


# satisfied_regret is the oracle's test (the plan's exact regret): a participant never uses it.
_TAKES: dict[str, set[str]] = {
    "fitted": _names(FittedParams) - {"satisfied_regret"},
    "observer": _names(ParticipantParams) - {"satisfied_regret"},
}


def default_person(participants: tuple[str, ...]) -> str:
    """A version's default person: its first participant, else the oracle (v0)."""
    return participants[0] if participants else ORACLE


def _check_keys(spec: HumanSpec, takes: set[str]) -> dict[str, Any]:
    unknown = sorted(set(spec.kwargs) - takes)
    if unknown:
        raise ValueError(
            f"person kwargs {unknown} are not parameters of person {spec.label()!r}; "
            f"it takes {sorted(takes)}"
        )
    return dict(spec.kwargs)


def as_used(spec: HumanSpec, participants: tuple[str, ...]) -> HumanSpec:
    """``spec`` as the study env with these ``participants`` uses it (defaults filled in);
    ValueError naming a person the version lacks or a parameter the person does not use."""
    name = spec.name
    if name in ("fitted", "observer"):
        if name not in participants:
            valid = [*participants, ORACLE] if participants else [ORACLE]
            raise ValueError(
                f"person {name!r} is not one of this version's people: {valid} or a human "
                "model's name"
            )
        shared = {"sigma", "bias"} if name == "observer" else set()
        spec.refuse({"sigma", "bias", "beta"} - shared, shared | _TAKES[name])
        kwargs = _check_keys(spec, _TAKES[name])
        params = ParticipantParams if name == "observer" else FittedParams
        params(**kwargs)  # bad values fail here, not at the first reset
        given = spec.given()
        return HumanSpec(
            name, **{k: given.get(k, SHARED_DEFAULTS[k]) for k in shared}, kwargs=kwargs
        )
    model, push = _oracle_parts(spec)
    PushParams(**push)
    return dataclasses.replace(
        spec,
        sigma=model.sigma,
        bias=model.bias,
        beta=model.beta,
        kwargs={**model.kwargs, **push},
    )


def _oracle_parts(spec: HumanSpec) -> tuple[HumanSpec, dict[str, Any]]:
    """The oracle's human model (as used) and its push parameters, from one spec."""
    push_keys = _names(PushParams)
    push = {k: v for k, v in spec.kwargs.items() if k in push_keys}
    own = {k: v for k, v in spec.kwargs.items() if k not in push_keys}
    model = spec.name if spec.name != ORACLE else ORACLE_MODEL
    try:
        used = dataclasses.replace(spec, name=model, kwargs=own).as_used()
    except ValueError as e:
        if spec.name == ORACLE:
            raise ValueError(f"{e} (person 'oracle' corrects with the 'nominal' model)") from None
        raise
    return used, push


def build(
    spec: HumanSpec, task: StudyTask, theta_star: np.ndarray, rng: np.random.Generator
) -> StudyPerson:
    """The simulated person of a resolved ``spec`` (``as_used``) for one episode."""
    if spec.name == "fitted":
        params = population.shipped().draw(rng, task.number)
        if spec.kwargs:
            params = dataclasses.replace(params, **spec.kwargs)
        return FittedParticipant(task, theta_star, rng, params=params)
    if spec.name == "observer":
        sigma, bias = spec.sigma or 0.0, spec.bias or 0.0
        return Participant(task, theta_star, rng, sigma=sigma, bias=bias, **spec.kwargs)
    model, push = _oracle_parts(spec)
    shared: dict[str, Any] = model.given()
    return SimulatedUser(
        task, theta_star, rng, model=model.name, human_kwargs=dict(model.kwargs), **shared, **push
    )


__all__ = ["ORACLE", "StudyPerson", "as_used", "build", "default_person"]
