"""A batched trajectory optimiser for linear rewards: projected gradient ascent from many starts.

It maximises Σ_{t=1..T} θ·φ(x_t) over the T step increments Δ_t (x_t = x_{t−1} + Δ_t) under a
per-axis step bound |Δ_t| ≤ b and a position box low ≤ x_t ≤ high. Both constraints hold on
*every iterate*, not only after the optimisation: clipping a plan afterwards returns a plan
worse than the optimiser believed, which makes regret come out negative. The projection is

    x_t = clip(x0 + Σ_{τ≤t} clip(Δ_τ, −b, b), low, high),   Δ_t = x_t − x_{t−1}.

Clipping to a box is a per-axis 1-Lipschitz map, so the projected increments still satisfy
|Δ_t| ≤ b, and the map leaves every feasible plan unchanged (a valid, if non-Euclidean,
projection; the Euclidean one would need a QP per iterate).

The ascent step is Adam-normalised per increment: ∂/∂Δ_t = Σ_{τ≥t} ∂R/∂x_τ differs by a factor
T between the first and the last increment, and a plain gradient step leaves the last ones
barely moving. The step size decays linearly to 0, so plans settle onto non-smooth optima
(reaching an object, where the distance feature has a kink) instead of circling them.

All starts run at once, vectorised over batch × starts; the best plan per row is returned. The
random starts come from a fixed seed and are shared by every row, so a row's plan depends only
on its (θ, x0): plan() is deterministic, and equal rows (θ̂ = θ*) give identical plans, so regret
is exactly 0 there.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

FeatureFn = Callable[[np.ndarray], np.ndarray]
"""φ: (..., s) -> (..., d)."""
JacobianFn = Callable[[np.ndarray], np.ndarray]
"""∂φ/∂x: (..., s) -> (..., d, s)."""
WalkFn = Callable[[np.ndarray, float], None]
"""A further constraint (keep-out zones, a reachable set), applied after the box: rewrites the
waypoints ``pos`` (..., T+1, s), row 0 = x0, in place, one step after the other, each within the
step bound of the one before it."""

PLANNER_SEED = 20240417
"""Seed of the random starts: fixed, so that planning is a deterministic function."""

_BETA1, _BETA2, _EPS = 0.9, 0.999, 1e-12


def straight_line_starts(x0: np.ndarray, targets: np.ndarray, steps: int, bound: float):
    """Increments heading from x0 (B, s) towards each target (k, s): (B, k, T, s).

    Full per-axis speed until the target is reached, then zero.
    """
    diff = targets[None, :, :] - x0[:, None, :]
    t = np.arange(1, steps + 1)[None, None, :, None]
    reach = np.clip(diff[:, :, None, :], -bound * t, bound * t)  # offset after t steps
    return np.diff(reach, axis=2, prepend=0.0)


class _Buffers:
    """The plan buffer ``pos`` (B, S, T+1, s), row 0 = x0 (it never changes), and x0 and the
    box spread to the waypoints' shape (B, S, T, s).

    Full-size operands keep numpy's inner loops long: broadcasting a (B, 1, 1, s) operand makes
    them s = 3 elements long, 5-10x slower at the planner's sizes. The values, and so the
    results, are the same.
    """

    def __init__(
        self,
        theta: np.ndarray,
        x0: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
        n_starts: int,
        steps: int,
        walk: WalkFn | None = None,
    ):
        b, s = x0.shape
        self.walk = walk
        self.pos = np.empty((b, n_starts, steps + 1, s))
        self.pos[..., 0, :] = x0[:, None, :]
        shape = (b, n_starts, steps, s)
        self.start, self.lo, self.hi = (
            np.broadcast_to(a, shape).copy() for a in (x0[:, None, None, :], lo, hi)
        )
        # θ spread per feature, (d, B, S, T, s); scratch for the θ-weighted Jacobian (grad,
        # term) and for the Adam step (work, den), all of the increments' shape.
        d = theta.shape[1]
        self.theta = np.broadcast_to(theta.T[:, :, None, None, None], (d, *shape)).copy()
        self.grad, self.term, self.work, self.den = (np.empty(shape) for _ in range(4))

    def project(self, delta: np.ndarray, bound: float) -> np.ndarray:
        """Write the feasible waypoints for raw increments ``delta`` into ``pos``; return the
        feasible increments (see the module docstring). ``delta`` is overwritten: the returned
        increments live in it (no large temporaries)."""
        pos = self.pos
        way = pos[..., 1:, :]
        np.cumsum(np.clip(delta, -bound, bound, out=delta), axis=-2, out=way)
        way += self.start
        np.clip(way, self.lo, self.hi, out=way)
        if self.walk is not None:
            self.walk(pos, bound)
        return np.subtract(way, pos[..., :-1, :], out=delta)

    def ascent(self, jac: np.ndarray) -> np.ndarray:
        """∂R/∂x_t = Σ_i θ_i ∂φ_i/∂x_t, from the Jacobians (B, S, T, d, s) -> (B, S, T, s).

        Products summed in feature order (the closing + 0.0 turns a −0 total into +0, as a sum
        from zero does): elementwise operations, so the same bits on every CPU, where
        ``np.matmul(θ, J)``, equal within rounding, sums in an order its BLAS kernel chooses.
        Without matmul's per-point tiny matrix products. Overwritten by the next call.
        """
        grad, term = self.grad, self.term
        np.multiply(self.theta[0], jac[..., 0, :], out=grad)
        for i in range(1, len(self.theta)):
            grad += np.multiply(self.theta[i], jac[..., i, :], out=term)
        grad += 0.0
        return grad


def plan_linear_reward(
    features: FeatureFn,
    jacobian: JacobianFn,
    theta: np.ndarray,
    x0: np.ndarray,
    *,
    steps: int,
    step_bound: float,
    low: np.ndarray,
    high: np.ndarray,
    targets: np.ndarray | None = None,
    away: bool = True,
    n_random: int = 12,
    n_iters: int = 60,
    lr: float = 0.5,
    prune_after: int = 20,
    keep: int = 4,
    walk: WalkFn | None = None,
) -> np.ndarray:
    """Plans maximising Σ_{t=1..T} θ·φ(x_t) from x0: theta (B, d), x0 (B, s) -> (B, T+1, s).

    Starts: the zero plan, a straight line towards (and, if ``away``, one away from) each of
    ``targets`` (k, s) (points worth heading to, e.g. objects), and ``n_random`` seeded random
    plans.
    ``lr`` is the first Adam step as a fraction of ``step_bound``. After ``prune_after``
    iterations only the ``keep`` best starts per row go on. Row 0 of each plan is x0.
    A start outside the box is allowed: the box is widened per row to contain it, so that the
    plan's steps stay bounded. ``walk`` (``WalkFn``), if given, is applied after the box on every
    iterate (keep-out zones, a reachable set: constraints a box cannot say).
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=np.float64))
    x0 = np.atleast_2d(np.asarray(x0, dtype=np.float64))
    if theta.ndim != 2 or x0.ndim != 2 or theta.shape[0] != x0.shape[0]:
        raise ValueError(
            f"theta (B, d) and x0 (B, s) need one batch size, got {theta.shape}, {x0.shape}"
        )
    if steps < 1 or not step_bound > 0 or n_iters < 0:
        raise ValueError(
            f"need steps >= 1, step_bound > 0, n_iters >= 0; got {steps}, {step_bound}, {n_iters}"
        )
    b, s = x0.shape
    lo = np.minimum(low, x0)[:, None, None, :]
    hi = np.maximum(high, x0)[:, None, None, :]

    starts = [np.zeros((b, 1, steps, s))]
    if targets is not None and len(targets):
        toward = straight_line_starts(x0, np.atleast_2d(targets), steps, step_bound)
        starts += [toward, -toward] if away else [toward]
    if n_random:
        rand = np.random.default_rng(PLANNER_SEED).uniform(-1, 1, size=(n_random, steps, s))
        starts.append(np.broadcast_to(step_bound * rand, (b, n_random, steps, s)))
    delta = np.concatenate(starts, axis=1)  # (B, S, T, s)

    th_row = theta[:, None, None, :]
    # ∂/∂Δ_t = Σ_{τ≥t} ∂R/∂x_τ: a reverse cumulative sum, as one matmul with a triangle.
    upper = np.triu(np.ones((steps, steps)))

    def value_of(way: np.ndarray) -> np.ndarray:
        return np.sum(features(way) * th_row, axis=(-2, -1))  # (B, S)

    buffers = _Buffers(theta, x0, lo, hi, delta.shape[1], steps, walk)
    pos = buffers.pos
    delta = buffers.project(delta, step_bound)
    initial = pos.copy()  # ascent is not monotone: a start can beat its own end point
    initial_value = value_of(initial[..., 1:, :])
    m = np.zeros_like(delta)
    v = np.zeros_like(delta)
    for k in range(n_iters):
        if k == prune_after and delta.shape[1] > keep:
            # Continue with the most promising starts only: most of the cost is in the starts.
            score = np.maximum(value_of(pos[..., 1:, :]), initial_value)
            best = np.argsort(-score, axis=1, kind="stable")[:, :keep]
            rows = np.arange(b)[:, None]
            delta, m, v = delta[rows, best], m[rows, best], v[rows, best]
            initial, initial_value = initial[rows, best], initial_value[rows, best]
            buffers = _Buffers(theta, x0, lo, hi, keep, steps, walk)
            pos = buffers.pos
            delta = buffers.project(delta, step_bound)
        # The Adam step in place: at these sizes allocating temporaries costs as much as the
        # arithmetic. The same operations in the same order as
        # m = β1 m + (1 − β1) g;  v = β2 v + (1 − β2) g g;  Δ += step·m / (√(v / c2) + ε).
        grad = np.matmul(upper, buffers.ascent(jacobian(pos[..., 1:, :])))
        buf, den = buffers.work, buffers.den
        m *= _BETA1
        m += np.multiply(grad, 1 - _BETA1, out=buf)
        v *= _BETA2
        np.multiply(grad, 1 - _BETA2, out=buf)
        v += np.multiply(buf, grad, out=buf)
        c1, c2 = 1 - _BETA1 ** (k + 1), 1 - _BETA2 ** (k + 1)
        step = step_bound * lr * (1.0 - k / n_iters) / c1
        np.sqrt(np.divide(v, c2, out=den), out=den)
        den += _EPS
        delta += np.divide(np.multiply(m, step, out=buf), den, out=buf)
        delta = buffers.project(delta, step_bound)

    value = value_of(pos[..., 1:, :])
    worse = initial_value > value
    pos[worse] = initial[worse]
    value[worse] = initial_value[worse]
    return pos[np.arange(b), np.argmax(value, axis=1)]
