"""The corrections of N simulated humans, one per sub-env of a vector env, in one batched call.

Each sub-env keeps its own human (built exactly as the single env builds it, with the sub-env's
generator), so every human draws its candidates and noise from its own stream, in the single
env's order. What is batched is the choice: for the eq. M6 teacher (``NominalHuman``) the
candidates of all humans go through one ``optimal_correction`` call, and the noise through
``perturb``. Any other human answers through its own ``act``, one call per sub-env.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from strol_gym.humans import (
    Human,
    NominalHuman,
    _accepted,
    human_factory,
    make_human,
    optimal_correction,
    perturb,
)
from strol_gym.tasks.base import Task


class _Drawn:
    """A stand-in generator whose ``standard_normal`` returns draws already made per human."""

    def __init__(self, z: np.ndarray) -> None:
        self._z = z

    def standard_normal(self, shape: tuple[int, ...]) -> np.ndarray:
        if tuple(shape) != self._z.shape:
            raise ValueError(f"expected draws of shape {self._z.shape}, asked for {shape}")
        return self._z


def _same_nominal(humans: Sequence[Human]) -> bool:
    """Whether every human is a plain ``NominalHuman`` with one task, K, σ and ε."""
    first = humans[0]
    if type(first) is not NominalHuman:
        return False
    key = (first.task, first.n_candidates, first.sigma, first.bias)
    return all(
        type(h) is NominalHuman and (h.task, h.n_candidates, h.sigma, h.bias) == key for h in humans
    )


def batched_corrections(
    humans: Sequence[Human], x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray
) -> np.ndarray:
    """u_H (B, a) of ``humans[b].act(x[b], u_r[b], theta_hat[b])`` for every b, batched
    where the human model allows (eq. M6 teachers), else one ``act`` per human."""
    if not len(humans):
        return np.zeros((0, u_r.shape[-1]))
    if _same_nominal(humans):
        h0 = humans[0]
        task, k = h0.task, h0.n_candidates
        cand = _candidates(task, [h.rng for h in humans], k)
        theta_star = np.stack([h.theta_star for h in humans])
        u = optimal_correction(task, x, u_r, theta_hat, theta_star, cand)
        z = np.concatenate([h.rng.standard_normal(u[:1].shape) for h in humans])
        return perturb(task, u, h0.sigma, h0.bias, _Drawn(z))
    return np.stack(
        [
            np.asarray(h.act(x[b], u_r[b], theta_hat[b]), dtype=np.float64)
            for b, h in enumerate(humans)
        ]
    )


def _candidates(task: Task, rngs: list[np.random.Generator], k: int) -> np.ndarray:
    """``task.candidate_actions(rng, 1, k)`` for each generator, stacked: (B, k + 1, a).

    For a task that keeps ``Task.candidate_actions`` only the uniform draws stay per generator;
    the zero action and the scaling by the bound, elementwise, run once on the batch."""
    if type(task).candidate_actions is not Task.candidate_actions:
        return np.concatenate([task.candidate_actions(rng, 1, k) for rng in rngs])
    a = task.action_bound
    draws = np.empty((len(rngs), k, task.action_dim))
    for b, rng in enumerate(rngs):
        draws[b] = rng.uniform(-1.0, 1.0, size=(k, task.action_dim))
    draws *= a
    out = np.zeros((len(rngs), k + 1, task.action_dim))
    out[:, 1:] = draws
    return out


class HumanMaker:
    """``make_human`` for many humans of one model: the factory and the keyword arguments its
    signature accepts are resolved once (``make_human`` does it per call), the first human is
    built and checked by ``make_human`` itself."""

    def __init__(self, human: Any, task: Task, **params: Any) -> None:
        self.human, self.task, self.params = human, task, params
        self._factory: Any = None

    def __call__(self, theta_star: np.ndarray, rng: np.random.Generator) -> Human:
        if self._factory is None:
            obj = make_human(self.human, self.task, theta_star, rng, **self.params)
            factory = human_factory(self.human)
            accepted = _accepted(factory)
            if accepted is not None:
                self.params = {k: v for k, v in self.params.items() if k in accepted}
            self._factory = factory
            return obj
        return self._factory(self.task, theta_star, rng, **self.params)
