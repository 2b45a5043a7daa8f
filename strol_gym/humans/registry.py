"""The registry of human models: names -> batched models or factories of single humans, and
the builders every caller uses (``make_human`` for one person, ``human_model`` for a batch)."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from strol_gym import checks
from strol_gym.humans.builtin import BoltzmannModel, ChangingModel, DriverModel, NominalModel
from strol_gym.humans.interface import Draws, Human, HumanModel, SimulatedHuman, needs_theta_hat
from strol_gym.humans.zoo import ZOO
from strol_gym.registry import Registry, call_piece
from strol_gym.tasks.base import Task

if TYPE_CHECKING:
    from typing_extensions import TypeIs

HUMAN_MODELS: dict[str, Any] = {
    "nominal": NominalModel,
    "boltzmann": BoltzmannModel,
    "driver": DriverModel,
    "changing": ChangingModel,
    **ZOO,
}
"""The built-in human models (the zoo of ``strol_gym.humans.zoo`` among them);
``register_human`` adds to it (through ``HUMANS``). An entry is a :class:`HumanModel` subclass
(batched) or any factory of single-sample humans."""

HumanFactory = Callable[..., Human]
SHARED_PARAMS = ("sigma", "bias", "beta")
"""What every human factory may receive from the env or the benchmark (contract: it gets only
those its signature declares)."""


def _is_model(obj: object) -> TypeIs[type[HumanModel]]:
    return isinstance(obj, type) and issubclass(obj, HumanModel)


HUMANS = Registry[HumanFactory | type[HumanModel]](
    "human",
    HUMAN_MODELS,
    callable_as="(task, theta_star, rng, **params) -> Human",
    hint=" naming a HumanModel subclass or a factory (task, theta_star, rng, sigma=, ...) -> Human",
)


def register_human(name: str, factory: type[HumanModel] | HumanFactory | str) -> None:
    """Make ``factory`` available as ``human=name`` in the envs, the benchmark and training.

    ``factory`` is a :class:`HumanModel` subclass (batched: training, vector envs and the
    Task-level loops ask it for whole batches), or any factory of single-sample humans, called
    as ``factory(task, theta_star, rng, sigma=..., bias=..., beta=..., **human_kwargs)``. Either
    gets only the keyword arguments its signature declares (all of them if it takes
    ``**kwargs``); it may be a lazy ``"module:attr"`` string.
    """
    HUMANS.register(name, factory)


def human_factory(human: str | HumanFactory | type[HumanModel]) -> HumanFactory:
    """The factory of single-sample humans for a registered name, a ``"module:attr"``, a
    :class:`HumanModel` subclass (its :class:`SimulatedHuman` adapter) or a callable; else
    ValueError."""
    factory = HUMANS.get(human) if isinstance(human, str) else human
    HUMANS.check(str(human), factory)
    if _is_model(factory):
        return SimulatedHuman.of(factory)
    return factory


def human_model(
    human: str | HumanFactory | type[HumanModel],
    task: Task,
    *,
    sigma: float = 0.0,
    bias: float = 0.0,
    beta: float = 50.0,
    **human_kwargs: Any,
) -> HumanModel:
    """The batched model of ``human`` with σ, ε, β and ``human_kwargs`` (those it declares).

    A factory of single-sample humans without a model is wrapped in :class:`PerSampleModel`,
    which builds one human per row: correct, general and slow."""
    factory = human_factory(human)
    params = _params(factory, {"sigma": sigma, "bias": bias, "beta": beta, **human_kwargs})
    model_class = getattr(factory, "model_class", None)
    if (
        isinstance(factory, type)
        and issubclass(factory, SimulatedHuman)
        and model_class is not None
    ):
        return model_class(task, **params)
    return PerSampleModel(factory, task, **params)


def _accepted(factory: HumanFactory) -> set[str] | None:
    """Keyword names ``factory`` declares (a model adapter: its model's); None when it takes
    ``**kwargs`` (or is opaque)."""
    target = getattr(factory, "model_class", None) or factory
    try:
        params = inspect.signature(target).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return None
    return {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}


def _params(factory: HumanFactory, params: dict[str, Any]) -> dict[str, Any]:
    """``params`` restricted to those the factory declares (all, if it takes ``**kwargs``)."""
    accepted = _accepted(factory)
    return params if accepted is None else {k: v for k, v in params.items() if k in accepted}


def check_human_kwargs(human: str | HumanFactory, human_kwargs: dict[str, Any] | None) -> dict:
    """``human_kwargs`` as a dict, else ValueError: not a mapping of names the factory declares,
    or one of the shared parameters (σ, ε, β are arguments of their own)."""
    human_kwargs = checks.mapping("human_kwargs", human_kwargs)
    shared = sorted(set(human_kwargs) & set(SHARED_PARAMS))
    if shared:
        raise ValueError(
            f"human_kwargs must not hold {shared}: pass them as arguments of their own"
        )
    accepted = _accepted(human_factory(human))
    unknown = [] if accepted is None else sorted(set(human_kwargs) - accepted)
    if accepted is not None and unknown:
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
    params = _params(factory, {"sigma": sigma, "bias": bias, "beta": beta, **human_kwargs})
    obj = call_piece("human", human, factory, task, theta_star, rng, **params)
    if not isinstance(obj, Human):
        raise ValueError(
            f"human {human!r} must return an object with act(x, u_r, theta_hat) and "
            f"theta_star, got {type(obj).__name__}"
        )
    return obj


class PerSampleModel(HumanModel):
    """A batch of any single-sample humans: a user's factory without a model, built per row.

    What makes it slow makes it general: one ``factory(task, θ*_b, rng, **params)`` per row and
    correction, each answering with its ``act``; the generator is the one the caller draws from.
    """

    def __init__(self, factory: Callable[..., Any], task: Task, **params: Any) -> None:
        super().__init__(task)
        self.factory, self.params = factory, params
        self.needs_theta_hat = True  # type: ignore[misc]  # unknown: assume it does

    def draw(self, rng: np.random.Generator, n: int) -> Draws:
        return Draws(np.zeros((n, 0, self.task.action_dim)), np.zeros((n, 0)), {"rng": rng})  # type: ignore[dict-item]  # the rows' own generator, not drawn numbers

    def corrections(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        rng = draws.extra["rng"]
        out = np.empty((len(x), self.task.action_dim))
        for b in range(len(x)):
            human = make_human(self.factory, self.task, theta_star[b], rng, **self.params)
            th = None if theta_hat is None else theta_hat[b]
            out[b] = human.act(x[b], u_r[b], th if needs_theta_hat(human) else None)
        return out
