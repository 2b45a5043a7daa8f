"""The three hand-designed baselines: Gradient, One (one-at-a-time) and MOF.

All three use the task's learning rule g = φ(x_H) − φ(x_R) (eq. P3) and θ̂ ← θ̂ + α·G (eq. P2).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from strol_gym import checks
from strol_gym.learners.protocol import LinearRuleLearner
from strol_gym.limits import check_size
from strol_gym.tasks.base import Task


class GradientLearner(LinearRuleLearner):
    """Gradient: G = g(x, u_H, u_R), the designer's original learning dynamics."""

    name = "gradient"

    def direction(self, x, u_h, u_r, theta) -> np.ndarray:
        return self.task.g(x, u_h, u_r)


class OneLearner(LinearRuleLearner):
    """One-at-a-time (Losey et al. 2022): only the component that best matches u_H changes.

    i* = argmax_i |g_i / s_i| with s = ``task.feature_scale`` (a typical range of each feature),
    so that a feature measured in larger units does not win by its units alone; G_i* = g_i*
    (the unscaled Gradient component) and every other component of G is 0. Ties go to the
    lowest index; g = 0 changes nothing.
    """

    name = "one"

    def direction(self, x, u_h, u_r, theta) -> np.ndarray:
        g = self.task.g(x, u_h, u_r)
        scale = np.asarray(self.task.feature_scale, dtype=np.float64)
        best = np.argmax(np.abs(g / scale), axis=-1)
        out = np.zeros_like(g)
        rows = np.arange(len(g))
        out[rows, best] = g[rows, best]
        return out


class MOFLearner(LinearRuleLearner):
    """MOF (misspecified objective functions, Bobu et al.): learn only from explained inputs.

    The robot learns (G = g) only when u_H is explained by some hypothesis θ in its feature
    space; otherwise G = 0 and θ̂ stays. The test asks whether u_H is a near-best action, for
    *some* reward direction w, among the admissible actions of the *same size*:

        score(u_H) = max_w  w·g(x, u_H, u_R) / max_{u ∈ A(‖u_H‖)} w·g(x, u, u_R)

    where A(r) holds ``n_candidates`` fixed directions (drawn once with
    ``task.candidate_actions`` and a fixed internal ``seed``), each rescaled to the size r of
    u_H (measured in units of a_max per axis) and clipped to the admissible box (grown to
    contain u_H when noise pushed u_H past a_max), plus u_H itself, so score ≤ 1. w ranges
    over ``n_hypotheses`` fixed unit directions, the ±axes and the direction of g(x, u_H, u_R).
    The input is accepted when score ≥ ``threshold`` (default 0.9: on the Robot task it accepts
    ~99 % of noise-free eq. M6 corrections, ~85 % at σ = 0.25 and ~45 % of uniformly random
    actions).

    The score is scale free: a small correction that moves the features the way some θ wants
    scores near 1, while effort spent along directions that no feature sees (g ≈ 0 although
    ‖u_H‖ is large) scores near 0. To first order it is the cosine between u_H and the best
    same-size action of the hypothesis that fits u_H best. u_H = 0 (no correction) scores 0.
    """

    name = "mof"

    def __init__(
        self,
        task: Task,
        threshold: float = 0.9,
        n_candidates: int = 256,
        n_hypotheses: int = 64,
        seed: int = 0,
    ) -> None:
        super().__init__(task)
        self.threshold = float(checks.number("threshold", threshold, high=1.0))
        checks.number("n_candidates", n_candidates, low=1, integer=True)
        checks.number("n_hypotheses", n_hypotheses, low=0, integer=True)
        n_candidates = check_size("n_candidates", n_candidates)
        n_hypotheses = check_size("n_hypotheses", n_hypotheses, low=0)
        checks.number("seed", seed, low=0, integer=True)
        self.n_candidates = int(n_candidates)
        self.n_hypotheses = int(n_hypotheses)
        self.seed = int(seed)
        rng = np.random.default_rng(self.seed)
        a = np.asarray(task.action_bound, dtype=np.float64)
        cand = task.candidate_actions(rng, 1, self.n_candidates)[0] / a
        norms = np.linalg.norm(cand, axis=-1)
        self._unit_actions = cand[norms > 0] / norms[norms > 0, None]  # (K, a), a-normalised
        w = rng.standard_normal((self.n_hypotheses, task.dim))
        w = np.concatenate([w, np.eye(task.dim), -np.eye(task.dim)])
        self._hypotheses = w / np.linalg.norm(w, axis=-1, keepdims=True)  # (M, d)

    def config(self) -> dict[str, Any]:
        return {
            "threshold": self.threshold,
            "n_candidates": self.n_candidates,
            "n_hypotheses": self.n_hypotheses,
            "seed": self.seed,
        }

    def explanation_score(
        self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None = None
    ) -> np.ndarray:
        """The score above for a batch: (B, s), (B, a), (B, a) -> (B,). Also works on 1-D."""
        task = self.task
        single = np.ndim(x) == 1
        x, u_h = np.atleast_2d(x).astype(np.float64), np.atleast_2d(u_h).astype(np.float64)
        u_r = np.zeros_like(u_h) if u_r is None else np.atleast_2d(u_r).astype(np.float64)
        b = max(len(x), len(u_h), len(u_r))
        x, u_h, u_r = (np.broadcast_to(v, (b, v.shape[1])) for v in (x, u_h, u_r))
        a = np.asarray(task.action_bound, dtype=np.float64)
        g_h = task.g(x, u_h, u_r)  # (B, d)
        size = np.linalg.norm(u_h / a, axis=-1)  # (B,)
        # The admissible box, grown just enough to hold u_H (noise can push u_H past a_max).
        box = a * np.maximum(1.0, np.abs(u_h / a).max(axis=-1, keepdims=True))  # (B, a)
        alt = size[:, None, None] * self._unit_actions[None] * a
        alt = np.clip(alt, -box[:, None], box[:, None])
        alt = np.concatenate([alt, u_h[:, None]], axis=1)  # (B, K+1, a)
        g_alt = task.g(x[:, None], alt, u_r[:, None])  # (B, K+1, d)
        g_norm = np.linalg.norm(g_h, axis=-1, keepdims=True)
        own = np.divide(g_h, g_norm, out=np.zeros_like(g_h), where=g_norm > 0)
        w = np.concatenate(
            [np.broadcast_to(self._hypotheses, (b, *self._hypotheses.shape)), own[:, None]], axis=1
        )  # (B, M, d)
        num = np.einsum("bmd,bd->bm", w, g_h)
        den = np.einsum("bkd,bmd->bkm", g_alt, w).max(axis=1)
        ratio = np.divide(num, den, out=np.full_like(num, -np.inf), where=den > 0)
        score = ratio.max(axis=1)
        score = np.where(g_norm[:, 0] > 0, score, 0.0)
        return score[0] if single else score

    def accepts(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None = None) -> np.ndarray:
        """Whether MOF learns from each input (bool, (B,) or scalar)."""
        return self.explanation_score(x, u_h, u_r) >= self.threshold

    def direction(self, x, u_h, u_r, theta) -> np.ndarray:
        g = self.task.g(x, u_h, u_r)
        keep = self.accepts(x, u_h, u_r)
        return np.where(keep[:, None], g, 0.0)
