"""The batched choices of simulated humans: pure functions of a batch of states, θ*, θ̂ and
candidate actions, shared by every human model, the Tasks and the tests.

Noise and bias are fractions of the action bound a_max (docs/benchmark.md, "Conditions"):
δ ~ N(ε·a_max, (σ·a_max)²).
"""

from __future__ import annotations

import numpy as np

from strol_gym.tasks.base import Task


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
    """
    g = task.g(x[:, None, :], candidates, u_r[:, None, :])  # (B, K, d)
    # θ* − (θ̂ + α g) one feature at a time, on (B, K) planes: the numbers of broadcasting
    # (B, 1, d) against (B, K, d), whose inner loops are only d long (several times slower).
    resid = np.empty_like(g)
    for j in range(g.shape[-1]):
        col = np.multiply(g[..., j], task.alpha, out=resid[..., j])
        col += theta_hat[:, j, None]
        np.subtract(theta_star[:, j, None], col, out=col)
    best = np.argmin(np.einsum("bkd,bkd->bk", resid, resid), axis=1)
    return candidates[np.arange(len(candidates)), best]


def boltzmann_correction(
    task: Task,
    x: np.ndarray,
    u_r: np.ndarray,
    theta_star: np.ndarray,
    candidates: np.ndarray,
    beta: float,
    rng: np.random.Generator,
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


def driver_correction(
    task: Task,
    x: np.ndarray,
    u_r: np.ndarray,
    theta_star: np.ndarray,
    candidates: np.ndarray,
    horizon: int,
) -> np.ndarray:
    """A short-horizon driver, batched: the candidate u maximising Σ_{t=1..horizon} θ*·φ(x_t)
    when u (and the robot's u_R) act for the first step and both coast (zero action) after it.
    Acting for itself, not to teach: it ignores θ̂. Coasting, rather than repeating u, lets a
    car value "steer now, then hold the wheel" without the plan turning it around.

    Shapes: x (B, s), u_r (B, a), theta_star (B, d), candidates (B, K, a) -> (B, a).
    """
    if int(horizon) < 1:
        raise ValueError(f"horizon must be an integer >= 1, got {horizon}")
    xs = task.dynamics(x[:, None, :], candidates, u_r[:, None, :])
    total = np.einsum("bkd,bd->bk", task.features(xs), theta_star)
    zero = np.zeros((1, 1, candidates.shape[-1]))
    for _ in range(int(horizon) - 1):
        xs = task.dynamics(xs, zero, zero)
        total += np.einsum("bkd,bd->bk", task.features(xs), theta_star)
    return candidates[np.arange(len(candidates)), np.argmax(total, axis=1)]


def perturb(
    task: Task, u: np.ndarray, sigma: float, bias: float, rng: np.random.Generator
) -> np.ndarray:
    """u + δ with δ ~ N(ε·a_max, (σ·a_max)²) per component. Draws even when σ = 0 (pairing)."""
    a = task.action_bound
    return u + bias * a + sigma * a * rng.standard_normal(u.shape)
