"""The batched choices of simulated humans: pure functions of a batch of states, θ*, θ̂ and
candidate actions, shared by every human model, the Tasks and the tests. ``driver_correction``
lives with the Tasks (``strol_gym.tasks.driver``: the highway Task's robot policy predicts the
human with it) and is re-exported here.

Noise and bias are fractions of the action bound a_max (docs/benchmark.md, "Conditions"):
δ ~ N(ε·a_max, (σ·a_max)²).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from strol_gym.compiled import use_fast
from strol_gym.tasks.base import Task, add_noise
from strol_gym.tasks.driver import driver_correction as driver_correction


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
    With compiled kernels on (``strol_gym.compiled``), a Task's own kernel (``Task.m6_choice``)
    searches instead: the same choice, bit for bit.
    """
    if use_fast():
        best = task.m6_choice(x, u_r, theta_hat, theta_star, candidates)
        if best is not None:
            if len(best) == 1:  # one person: a slice's copy, the same row as below
                return candidates[:1, int(best[0])].copy()
            return candidates[np.arange(len(candidates)), best]
    g = task.g_planes(x[:, None, :], candidates, u_r[:, None, :])  # (d, B, K)
    # θ* − (θ̂ + α g) and its squared norm one feature at a time, on (B, K) planes: the
    # numbers of broadcasting (B, 1, d) against (B, K, d), whose inner loops are only d long.
    # One person: θ̂ and θ* as scalars (numpy's broadcasting of (1, 1) arrays costs more).
    one = len(g[0]) == 1
    th_hat = theta_hat[0].tolist() if one else theta_hat[:, :, None].transpose(1, 0, 2)
    th_star = theta_star[0].tolist() if one else theta_star[:, :, None].transpose(1, 0, 2)
    norm: np.ndarray | None = None
    for j in range(len(g)):
        col = np.multiply(g[j], task.alpha)
        col += th_hat[j]
        np.subtract(th_star[j], col, out=col)
        col *= col
        norm = col if norm is None else np.add(norm, col, out=norm)
    assert norm is not None  # g has d >= 1 rows
    best = np.argmin(norm, axis=1)
    return candidates[np.arange(len(candidates)), best]


def boltzmann_correction(
    task: Task,
    x: np.ndarray,
    u_r: np.ndarray,
    theta_star: np.ndarray,
    candidates: np.ndarray,
    beta: float,
    rng: UniformDraws,
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


class NormalDraws(Protocol):
    """What ``perturb`` draws from: a ``np.random.Generator``, or draws already made
    (``humans.interface.Replayed``), so the batched choices can replay them."""

    def standard_normal(self, size: tuple[int, ...], /) -> np.ndarray: ...


class UniformDraws(Protocol):
    """What the Boltzmann choice draws from: a ``np.random.Generator`` or replayed draws."""

    def random(self, size: tuple[int, ...], /) -> np.ndarray: ...


def perturb(
    task: Task, u: np.ndarray, sigma: float | np.ndarray, bias: float, rng: NormalDraws
) -> np.ndarray:
    """u + δ with δ ~ N(ε·a_max, (σ·a_max)²) per component (σ may vary per row, (n, 1)).
    Draws even when σ = 0 (pairing)."""
    return add_noise(task, u, sigma, bias, rng.standard_normal(u.shape))
