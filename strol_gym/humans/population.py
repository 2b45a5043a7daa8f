"""The corrections of many single humans at once: one per sub-env of a vector env.

Each sub-env keeps its own human, built exactly as the single env builds it with the sub-env's
generator, so every human draws from its own stream in the single env's order. What is batched
is the choice: humans of one model with equal parameters (``HumanModel.same_as``) are asked in
one ``HumanModel.corrections`` call over draws taken from each human's generator
(``HumanModel.draw_each``); any other human answers through its own ``act``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from strol_gym.humans.interface import Human, HumanModel, SimulatedHuman, needs_theta_hat
from strol_gym.humans.registry import _params, human_factory, make_human
from strol_gym.tasks.base import Task

if TYPE_CHECKING:
    from typing_extensions import TypeIs


def _one_model(humans: Sequence[Human]) -> TypeIs[Sequence[SimulatedHuman]]:
    """Whether every human is a SimulatedHuman of one model (so one batched call serves all)."""
    first = humans[0]
    if not isinstance(first, SimulatedHuman):
        return False
    model = first.model
    return all(
        isinstance(h, SimulatedHuman) and (h.model is model or h.model.same_as(model))
        for h in humans
    )


def batched_corrections(
    humans: Sequence[Human], x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray
) -> np.ndarray:
    """u_H (B, a) of ``humans[b].act(x[b], u_r[b], θ̂[b])`` for every b (θ̂ only to humans who
    need it), batched when all humans share one model."""
    if not len(humans):
        return np.zeros((0, u_r.shape[-1]))
    if _one_model(humans):
        model = humans[0].model
        k = _begin_each(humans)
        theta_star = np.stack([h.theta_initial for h in humans])
        rngs = [h.rng for h in humans]
        u = model.drawn_corrections(rngs, x, u_r, theta_star, theta_hat, k)
        if u is not None:
            return u
        draws = model.draw_each(rngs)
        return model.corrections(x, u_r, theta_star, draws, theta_hat, k)
    return np.stack(
        [
            np.asarray(
                h.act(x[b], u_r[b], theta_hat[b] if needs_theta_hat(h) else None),
                dtype=np.float64,
            )
            for b, h in enumerate(humans)
        ]
    )


def _begin_each(humans: Sequence[SimulatedHuman]) -> np.ndarray:
    """Each person's ``begin()``, their correction indices (B,): for people of one model who
    hold θ* itself, its bookkeeping in one pass (no call and 0-d array each)."""
    if type(humans[0].model).preference is not HumanModel.preference or any(
        kind.begin is not SimulatedHuman.begin for kind in {type(h) for h in humans}
    ):
        return np.array([h.begin() for h in humans])
    k = np.fromiter((h.n_acts for h in humans), dtype=np.int64, count=len(humans))
    for h in humans:
        h.theta_star = h.theta_initial
        h.n_acts += 1
    return k


class HumanMaker:
    """``make_human`` for many humans of one model: the factory and the keyword arguments its
    signature accepts are resolved once (``make_human`` does it per call); the first human is
    built and checked by ``make_human`` itself."""

    def __init__(self, human: Any, task: Task, **params: Any) -> None:
        self.human, self.task, self.params = human, task, params
        self._factory: Any = None
        self._person: type[SimulatedHuman] = SimulatedHuman
        self._model: Any = None

    def __call__(self, theta_star: np.ndarray, rng: np.random.Generator) -> Human:
        if self._factory is None:
            obj = make_human(self.human, self.task, theta_star, rng, **self.params)
            self._factory = human_factory(self.human)
            self.params = _params(self._factory, self.params)
            # People of one model share it (built and checked once, by make_human).
            if isinstance(obj, SimulatedHuman):
                self._person, self._model = type(obj), obj.model
            return obj
        if self._model is not None:
            return self._person.of_model(self._model, theta_star, rng)
        return self._factory(self.task, theta_star, rng, **self.params)
