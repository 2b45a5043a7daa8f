"""The corrections of N simulated humans, one per sub-env of a vector env, in one batched call.

Each sub-env keeps its own human (built exactly as the single env builds it, with the sub-env's
generator), so every human draws its candidates and noise from its own stream, in the single
env's order. What is batched is the choice: for the eq. M6 teacher (``NominalHuman``) the
candidates of all humans go through one ``optimal_correction`` call, and the noise through
``perturb``. Any other human answers through its own ``act``, one call per sub-env.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from strol_gym.humans import Human, NominalHuman, optimal_correction, perturb


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
        cand = np.concatenate([task.candidate_actions(h.rng, 1, k) for h in humans])
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
