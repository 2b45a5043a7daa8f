"""A Bayesian learner: a particle posterior over θ with a Boltzmann model of the human.

Not one of the paper's five rules; the principled baseline a researcher comparing learning
rules asks for. It works for any Task: it needs only ``task.g``, the candidate
actions and the prior modes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from strol_gym import checks
from strol_gym.learners.protocol import (
    LinearRuleLearner,
    as_theta,
    batch_inputs,
    checked_theta,
)
from strol_gym.limits import check_size
from strol_gym.priors import HedgedPrior, check_theta_range
from strol_gym.tasks.base import Task

LIKELIHOODS = ("reward", "teacher")
PRIORS = ("designer", "task")
DEFAULT_BETAS = (1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0)
CHUNK = 1 << 21
"""Largest rows × particles × candidates block scored at once (bounds memory to ~16 MB)."""


class BayesLearner(LinearRuleLearner):
    """Posterior mean of θ under a Boltzmann model of the human's correction (particle filter).

    **Observation model.** The human picks u_H among the admissible actions with probability
    P(u_H | θ, β) ∝ exp(β·s_θ(u_H)), normalised over ``n_candidates`` fixed admissible actions
    (drawn once with ``task.candidate_actions`` and the internal ``candidate_seed``) plus u_H:

    - ``likelihood="reward"`` (default): s_θ(u) = θ·g(x, u, u_R), the Task's reward gained by
      the correction (R(x_H, θ) − R(x_R, θ) for linear R). The human is assumed noisily
      optimal for its own reward, not a teacher.
    - ``likelihood="teacher"``: s_θ(u) = ‖θ − θ̂‖² − ‖θ − (θ̂ + α g(x, u, u_R))‖², how much the
      correction moves the robot's estimate θ̂ toward θ: a Boltzmann version of the eq. M6
      teacher that the benchmark's nominal human is.

    g over the candidates does not depend on θ, so it is computed once per update; the scores
    of every particle for every candidate are one product (batch × particles × candidates).

    **β.** ``beta`` is one value (fixed) or a grid carried jointly with θ: each particle holds a
    (θ, β) pair, β drawn uniformly from the grid, so the posterior also says how rational this
    human is. (Only βθ enters the reward likelihood: the prior on θ fixes the scale.)

    **Prior** (``prior="designer"``, default): the designer's bimodal prior, the one StROL's ĝ
    was trained with (modes ``task.prior_modes``, jitter ``mode_jitter`` = 0.1 as in the paper),
    mixed with weight ``broad_weight`` with a broad Gaussian N(θ0, s² I), θ0 the modes' mean and
    s the largest |mode entry| (``strol_gym.priors.HedgedPrior``): the designer's hedge that
    this human may fit neither mode. It is *not* the distribution θ* is drawn from in the
    benchmark's uniform-prior condition.
    ``prior="task"`` uses ``task.prior`` instead (the true θ* distribution: an oracle).
    ``broad_weight=0`` gives the designer's bimodal prior alone.

    **Resampling.** When the effective sample size of a row drops below ``ess_fraction`` ×
    ``n_particles``, that row is resampled systematically and every θ is jittered with a
    Gaussian kernel of ``bandwidth`` × the row's posterior standard deviation (per component),
    so the cloud does not collapse onto a few points.

    **Estimate.** θ̂ = the posterior mean. ``reset(θ0)`` shifts the prior sample so its mean is
    θ0 (default: the modes' mean, the paper's θ̂0 for every learner).

    **Randomness** comes from ``seed`` alone: the prior sample from Generator(seed) at every
    ``reset``, the resampling draws of the t-th update from Generator([seed, t]), shared by
    every row of a batch. So a run is a deterministic function of its inputs, a batch row
    equals the same interaction run alone, and paired runs see the same particles.
    """

    name = "bayes"

    def __init__(
        self,
        task: Task,
        n_particles: int = 2000,
        beta: float | Sequence[float] = DEFAULT_BETAS,
        likelihood: str = "reward",
        prior: str = "designer",
        broad_weight: float = 0.2,
        mode_jitter: float = 0.1,
        n_candidates: int = 64,
        ess_fraction: float = 0.5,
        bandwidth: float = 0.2,
        seed: int = 0,
        candidate_seed: int = 0,
    ) -> None:
        checks.number("n_particles", n_particles, low=1, integer=True)
        n_particles = check_size("n_particles", n_particles)
        betas = np.atleast_1d(checks.array("beta", beta, finite=False))
        if betas.ndim != 1 or len(betas) == 0 or not (np.isfinite(betas).all() and betas.min() > 0):
            raise ValueError(f"beta must be a finite number > 0 or a list of them, got {beta!r}")
        checks.name_in("likelihood", likelihood, LIKELIHOODS)
        checks.name_in("prior", prior, PRIORS)
        checks.number("broad_weight", broad_weight, low=0.0, high=1.0)
        checks.number("ess_fraction", ess_fraction, low=0.0, high=1.0)
        checks.number("mode_jitter", mode_jitter, low=0)
        checks.number("bandwidth", bandwidth, low=0)
        checks.number("n_candidates", n_candidates, low=1, integer=True)
        n_candidates = check_size("n_candidates", n_candidates)
        checks.number("seed", seed, low=0, integer=True)
        checks.number("candidate_seed", candidate_seed, low=0, integer=True)
        super().__init__(task)
        self.n_particles = int(n_particles)
        self.betas = betas
        self.likelihood = likelihood
        self.prior = prior
        self.broad_weight = float(broad_weight)
        self.mode_jitter = float(mode_jitter)
        self.n_candidates = int(n_candidates)
        self.ess_fraction = float(ess_fraction)
        self.bandwidth = float(bandwidth)
        self.seed = int(seed)
        self.candidate_seed = int(candidate_seed)
        cand = task.candidate_actions(np.random.default_rng(self.candidate_seed), 1, n_candidates)
        self._candidates = cand[0]  # (K + 1, a), index 0 is u = 0
        self.reset()

    # ------------------------------------------------------------------ prior and state
    def config(self) -> dict[str, Any]:
        return {
            "n_particles": self.n_particles,
            "beta": self.betas.tolist(),
            "likelihood": self.likelihood,
            "prior": self.prior,
            "broad_weight": self.broad_weight,
            "mode_jitter": self.mode_jitter,
            "n_candidates": self.n_candidates,
            "ess_fraction": self.ess_fraction,
            "bandwidth": self.bandwidth,
            "seed": self.seed,
            "candidate_seed": self.candidate_seed,
        }

    def sample_prior(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """n draws from the learner's prior over θ, (n, d)."""
        task = self.task
        if self.prior == "task":
            return np.asarray(task.prior.sample(rng, n), dtype=np.float64)
        prior = HedgedPrior(task.prior_modes, self.mode_jitter, self.broad_weight)
        return prior.sample(rng, n)

    def reset(self, theta0: np.ndarray | None = None) -> np.ndarray:
        task = self.task
        if theta0 is None:
            theta0 = np.asarray(task.prior_modes, dtype=np.float64).mean(axis=0)
        theta0 = as_theta("theta0", theta0, task.dim).copy()
        rng = np.random.default_rng(self.seed)
        self._updates = 0
        cloud = self.sample_prior(rng, self.n_particles)
        cloud += -cloud.mean(axis=0)
        self._particles = theta0[..., None, :] + cloud  # (N, d) or (B, N, d)
        idx = rng.integers(0, len(self.betas), size=self.n_particles)
        self._beta_idx = np.broadcast_to(idx, self._particles.shape[:-1]).copy()
        self._logw = np.zeros(self._particles.shape[:-1])
        self.theta = theta0
        return self.theta.copy()

    # ------------------------------------------------------------------ learning
    def log_likelihood(
        self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray
    ) -> np.ndarray:
        """log P(u_H | θ_n, β_n) for every row and particle, (B, N). Inputs are 2-D batches."""
        task = self.task
        b = len(x)
        cand = np.concatenate(
            [np.broadcast_to(self._candidates, (b, *self._candidates.shape)), u_h[:, None]], axis=1
        )  # (B, K + 1 + 1, a); the last one is u_H
        g = task.g(x[:, None], cand, u_r[:, None])  # (B, C, d): once per update, not per particle
        parts = np.broadcast_to(self._particles, (b, *self._particles.shape[-2:]))
        beta = self.betas[np.broadcast_to(self._beta_idx, parts.shape[:-1])]  # (B, N)
        if self.likelihood == "teacher":
            a = float(task.alpha)
            offset = -(a * a) * np.einsum("bcd,bcd->bc", g, g)  # (B, C)
            g = 2.0 * a * g
            base = theta_hat
        else:
            offset = np.zeros(g.shape[:2])
            base = np.zeros_like(theta_hat)
        out = np.empty(parts.shape[:-1])
        n, c = parts.shape[1], g.shape[1]
        step = max(1, CHUNK // (n * c))
        for lo in range(0, b, step):
            sl = slice(lo, lo + step)
            rel = parts[sl] - base[sl, None]
            score = np.matmul(rel, g[sl].transpose(0, 2, 1))  # (b, N, C), batched BLAS
            score += offset[sl, None]
            score *= beta[sl, :, None]
            score -= score.max(axis=-1, keepdims=True)
            chosen = score[..., -1].copy()  # u_H is the last candidate
            np.exp(score, out=score)
            out[sl] = chosen - np.log(score.sum(axis=-1))
        return out

    def update(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None = None) -> np.ndarray:
        x2, uh2, ur2, th2, single = batch_inputs(self.task, x, u_h, u_r, self.theta)
        saved = (self._particles, self._beta_idx, self._logw, self._updates)
        try:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                theta = self._update(x2, uh2, ur2, th2)
            if not (
                np.isfinite(theta).all()
                and np.isfinite(self._particles).all()
                and np.isfinite(self._logw).all()
            ):
                checked_theta(np.full_like(theta, np.nan))  # the same refusal as other learners
        except BaseException:  # a refused update changes nothing
            self._particles, self._beta_idx, self._logw, self._updates = saved
            raise
        self.theta = theta[0] if single else theta
        return self.theta.copy()

    def _update(
        self, x2: np.ndarray, uh2: np.ndarray, ur2: np.ndarray, th2: np.ndarray
    ) -> np.ndarray:
        """One Bayes step on fresh copies of the posterior (``update`` restores the old one if
        the result is not finite); returns the posterior means, (B, d)."""
        b, n = len(x2), self.n_particles
        rows = 1 if self._particles.ndim == 2 else len(self._logw)
        if rows not in (1, b):
            raise ValueError(
                f"x, u_h and u_r hold a batch of {b} but the posterior holds {rows} rows; "
                "reset() to start another batch"
            )
        shape = (b, n)
        self._particles = np.broadcast_to(self._particles, (*shape, self.task.dim)).copy()
        self._beta_idx = np.broadcast_to(self._beta_idx, shape).copy()
        self._logw = np.broadcast_to(self._logw, shape).copy()
        ll = self.log_likelihood(x2, uh2, ur2, th2)
        if not np.isfinite(ll).all():
            checked_theta(np.full(self.task.dim, np.nan))  # u_h or θ̂ overflow the likelihood
        logw = self._logw + ll
        self._updates += 1
        logw -= logw.max(axis=1, keepdims=True)
        w = np.exp(logw)
        w /= w.sum(axis=1, keepdims=True)
        self._logw = np.log(np.maximum(w, 1e-300))
        ess = 1.0 / np.sum(w * w, axis=1)
        low = np.flatnonzero(ess < self.ess_fraction * n)
        if len(low):
            self._resample(low, w[low])
            w[low] = 1.0 / n
        return np.einsum("bn,bnd->bd", w, self._particles)

    def _resample(self, rows: np.ndarray, w: np.ndarray) -> None:
        """Systematic resampling of ``rows`` (weights w, (R, N)), then a Gaussian jitter."""
        n = self.n_particles
        rng = np.random.default_rng([self.seed, self._updates])
        offset, eps = rng.random(), rng.standard_normal((n, self.task.dim))
        u = np.broadcast_to((offset + np.arange(n)) / n, (len(rows), n))
        cdf = np.cumsum(w, axis=1)
        cdf[:, -1] = 1.0
        # One searchsorted for all rows: row r's CDF and points are shifted into [r, r + 1].
        shift = np.arange(len(rows))[:, None]
        flat = np.searchsorted((cdf + shift).ravel(), (u + shift).ravel())
        idx = np.minimum(flat.reshape(u.shape) - n * shift, n - 1)
        take = np.take_along_axis
        parts = take(self._particles[rows], idx[..., None], axis=1)
        mean = np.einsum("rn,rnd->rd", w, self._particles[rows])
        var = np.einsum("rn,rnd->rd", w, (self._particles[rows] - mean[:, None]) ** 2)
        sd = self.bandwidth * np.sqrt(var)
        parts = parts + sd[:, None] * eps
        self._particles[rows] = parts
        self._beta_idx[rows] = take(self._beta_idx[rows], idx, axis=1)
        self._logw[rows] = -np.log(n)

    # ------------------------------------------------------------------ state
    def beta_posterior(self) -> np.ndarray:
        """P(β = betas[j] | data) per row: (len(betas),) or (B, len(betas))."""
        w = np.exp(self._logw - self._logw.max(axis=-1, keepdims=True))
        w /= w.sum(axis=-1, keepdims=True)
        onehot = self._beta_idx[..., None] == np.arange(len(self.betas))
        return np.einsum("...n,...nj->...j", w, onehot)

    def state_dict(self) -> dict[str, Any]:
        state = super().state_dict()
        state.update(
            particles=self._particles.copy(),
            beta_idx=self._beta_idx.copy(),
            logw=self._logw.copy(),
            updates=self._updates,
        )
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        # Read and check everything before anything is assigned: a failed load changes nothing.
        self.check_identity(state)
        missing = [k for k in ("particles", "beta_idx", "logw", "updates") if k not in state]
        if missing:
            raise ValueError(f"state lacks {self.name}'s posterior: missing key(s) {missing}")
        updates = state["updates"]
        if type(updates) is not int or updates < 0:
            raise ValueError(f"state['updates'] must be an integer >= 0, got {updates!r}")
        try:
            particles = np.asarray(state["particles"], dtype=np.float64).copy()
            beta_idx = np.asarray(state["beta_idx"]).copy()
            logw = np.asarray(state["logw"], dtype=np.float64).copy()
        except (TypeError, ValueError) as e:
            raise ValueError(f"state has an invalid {self.name} posterior ({e})") from None
        if beta_idx.dtype.kind not in "iu" or (
            beta_idx.size and (beta_idx.min() < 0 or beta_idx.max() >= len(self.betas))
        ):
            raise ValueError(
                f"state['beta_idx'] must hold integers in [0, {len(self.betas) - 1}] (indices "
                f"into beta), got dtype {beta_idx.dtype}"
                + (
                    f" and values in [{beta_idx.min()}, {beta_idx.max()}]"
                    if beta_idx.size and beta_idx.dtype.kind in "iu"
                    else ""
                )
            )
        for key, arr in (("particles", particles), ("logw", logw)):
            if not np.isfinite(arr).all():
                raise ValueError(f"state[{key!r}] must be finite (no NaN or inf)")
        check_theta_range("state['particles']", particles)  # θ samples: 1e308 overflows
        if particles.shape[:-1] != logw.shape or particles.shape[-1:] != (self.task.dim,):
            raise ValueError(
                f"state['particles'] {particles.shape} must be logw's shape {logw.shape} "
                f"+ ({self.task.dim},)"
            )
        if beta_idx.shape != logw.shape:
            raise ValueError(f"state['beta_idx'] {beta_idx.shape} must match logw {logw.shape}")
        if particles.ndim not in (2, 3) or particles.shape[-2] != self.n_particles:
            raise ValueError(
                f"state['particles'] must have shape ({self.n_particles}, {self.task.dim}) or "
                f"(B, {self.n_particles}, {self.task.dim}), got {particles.shape}"
            )
        theta = np.asarray(state.get("theta"), dtype=object)
        rows = 1 if particles.ndim == 2 else len(particles)
        ok_theta = theta.shape == (self.task.dim,) and rows == 1
        ok_theta = ok_theta or (particles.ndim == 3 and theta.shape == (rows, self.task.dim))
        if not ok_theta:
            raise ValueError(
                f"state['theta'] {theta.shape} does not match the posterior's {rows} row(s): "
                f"it must be ({self.task.dim},) for one row or ({rows}, {self.task.dim})"
            )
        super().load_state_dict(state)
        self._particles, self._beta_idx, self._logw = particles, beta_idx, logw
        self._updates = int(updates)


def teacher_bayes(task: Task, **kwargs: Any) -> BayesLearner:
    """``bayes-teacher``: BayesLearner with ``likelihood="teacher"`` (the eq. M6 teacher model)."""
    if "likelihood" in kwargs:
        raise ValueError("bayes-teacher fixes likelihood='teacher'; use 'bayes' to choose another")
    return BayesLearner(task, likelihood="teacher", **kwargs)
