"""strol-adaptive: StROL whose λ follows how well ĝ's corrections suit this human.

The paper's future work: infer online how far this human is from the one ĝ was trained for,
and set λ from that. Our estimate is the consistency of the human's corrections with ĝ's own
contributions, measured against the same statistic for the training human.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from strol_gym import checks
from strol_gym.learners.correction import MAX_LAM, StROLLearner
from strol_gym.learners.network import CorrectionNet
from strol_gym.learners.protocol import batch_inputs, check_state, checked_theta
from strol_gym.priors import MixturePrior
from strol_gym.tasks.base import Task

CALIBRATION_SEED = 11_500
"""Seed of the calibration runs (the learners branch's training range, 11000–11999)."""
_REFERENCE_CACHE: dict[tuple, float] = {}


def _cosine(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row-wise cos(a, b) and whether it is defined (both rows non-zero)."""
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    ok = (na > 0) & (nb > 0)
    return np.where(ok, np.sum(a * b, axis=-1) / np.where(ok, na * nb, 1.0), 0.0), ok


class AdaptiveStROLLearner(StROLLearner):
    """θ̂ ← θ̂ + α·(g + λ_t·ĝ), with λ_t set online per interaction (StROL's shipped ĝ).

    **Statistic.** After each update the learner remembers ĝ's direction. At the next
    correction it measures c_t = cos(g_t, ĝ_{t−1}): does this human's new correction continue
    the way ĝ last pushed θ̂ (c > 0), or undo it (c < 0)? A human whom ĝ suits accepts ĝ's push;
    a human ĝ misjudges (θ* away from the prior modes ĝ learned, or corrections unlike the
    training human's) pushes back. c̄ is the running mean of c_t in this interaction, shrunk
    toward the reference with ``prior_count`` pseudo-observations of c_ref.

    **Reference.** c_ref is the mean of c_t for the human ĝ was trained for: the eq. M6 human
    with the checkpoint's training σ and ε, θ* from the designer's bimodal prior, u_R = 0,
    simulated once per (task, weights, λ0) with seed ``CALIBRATION_SEED`` and this rule at
    fixed λ = λ0 (``calibration_runs`` runs of ``calibration_steps`` corrections), or given as
    ``reference``.

    **Rule.** λ_t = clip(λ0 · exp(``gain`` · (c̄ − c_ref)), 0, ``lam_max``). So λ = λ0 exactly
    (StROL) while the estimate says the human is the training human (c̄ = c_ref, and before the
    second correction); λ shrinks toward 0 (Gradient) for a human who keeps undoing ĝ's pushes
    and grows, up to ``lam_max`` (default 2 λ0), for one who keeps following them.

    **Assumptions.** The human corrects from the current θ̂ as a teacher does (eq. M6), so
    its next correction reflects where ĝ left θ̂; one interaction is short (5–10 corrections),
    so c̄ is noisy and ``gain`` trades reaction speed against that noise.
    """

    name = "strol-adaptive"
    kind = "strol"

    def __init__(
        self,
        task: Task,
        lam: float = 1.0,
        gain: float = 4.0,
        lam_max: float | None = None,
        prior_count: float = 1.0,
        reference: float | None = None,
        calibration_runs: int = 1000,
        calibration_steps: int = 5,
        checkpoint: str | Path | None = None,
        model: CorrectionNet | None = None,
    ) -> None:
        lam = float(checks.number("lam", lam, low=0, high=MAX_LAM, text=True))
        if lam_max is None:
            lam_max = 2.0 * lam
        lam_max = float(checks.number(f"lam_max (lam = {lam:g})", lam_max, low=lam, high=MAX_LAM))
        checks.number("gain", gain, low=0)
        checks.number("prior_count", prior_count, low=0)
        checks.number("calibration_runs", calibration_runs, low=1, integer=True)
        checks.number("calibration_steps", calibration_steps, low=2, integer=True)
        if reference is not None:
            checks.number("reference (a cosine)", reference, low=-1, high=1)
        super().__init__(task, lam=lam, checkpoint=checkpoint, model=model)
        self.gain = float(gain)
        self.lam_max = lam_max
        self.prior_count = float(prior_count)
        self.calibration_runs = int(calibration_runs)
        self.calibration_steps = int(calibration_steps)
        self.reference = float(reference) if reference is not None else self._calibrate()
        self._clear_stats()

    # ------------------------------------------------------------------ calibration
    def _calibrate(self) -> float:
        """c_ref for the training human (cached per task, weights and λ0 in this process)."""
        meta = self.checkpoint_meta or {}
        train = meta.get("training", {})
        key = (
            repr(self.task.describe()),
            self.checkpoint,
            id(self.model) if self.checkpoint is None else None,
            self.lam,
            self.calibration_runs,
            self.calibration_steps,
        )
        if key not in _REFERENCE_CACHE:
            from strol_gym.learners.simulate import simulate_errors

            task = self.task.with_prior(MixturePrior(self.task.prior_modes, jitter=0.1))
            probe = AdaptiveStROLLearner(
                task, lam=self.lam, gain=0.0, reference=0.0, model=self.model
            )
            simulate_errors(
                task,
                {"probe": probe},
                n_runs=self.calibration_runs,
                n_corrections=self.calibration_steps,
                sigma=float(train.get("sigma", 0.25)),
                bias=float(train.get("bias", 0.0)),
                seed=CALIBRATION_SEED,
            )
            _REFERENCE_CACHE[key] = float(probe._sum.sum() / max(probe._count.sum(), 1.0))
        return _REFERENCE_CACHE[key]

    # ------------------------------------------------------------------ state of an interaction
    def _clear_stats(self) -> None:
        lead = self.theta.shape[:-1]
        self._sum = np.zeros(lead)
        self._count = np.zeros(lead)
        self._last = np.zeros(self.theta.shape)

    def reset(self, theta0: np.ndarray | None = None) -> np.ndarray:
        out = super().reset(theta0)
        self._clear_stats()
        return out

    def current_lambda(self) -> np.ndarray:
        """λ_t that the next update uses: () or (B,)."""
        n0 = self.prior_count
        mean = (n0 * self.reference + self._sum) / np.maximum(n0 + self._count, 1e-12)
        mean = np.where(n0 + self._count > 0, mean, self.reference)
        lam = self.lam * np.exp(self.gain * (mean - self.reference))
        return np.clip(lam, 0.0, self.lam_max)

    def update(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None = None) -> np.ndarray:
        x2, uh2, ur2, th2, single = batch_inputs(self.task, x, u_h, u_r, self.theta)
        b = len(x2)
        total, count = np.broadcast_to(self._sum, (b,)), np.broadcast_to(self._count, (b,))
        last = np.broadcast_to(self._last, (b, self.task.dim))
        g_hat, g = self._correction_and_g(x2, uh2, ur2, th2)
        c, ok = _cosine(g, last)
        total, count = total + np.where(ok, c, 0.0), count + ok
        old = self._sum, self._count
        self._sum, self._count = total, count
        lam = np.atleast_1d(self.current_lambda())
        with np.errstate(over="ignore", invalid="ignore"):
            theta = th2 + self.task.alpha * (g + lam[:, None] * g_hat)
        try:
            theta = checked_theta(theta)
        except ValueError:
            self._sum, self._count = old
            raise
        self._last = g_hat.copy()
        if single:
            self._sum, self._count, self._last = total[0], count[0], self._last[0]
            self.theta = theta[0]
        else:
            self.theta = theta
        return self.theta.copy()

    # ------------------------------------------------------------------ config and state
    def config(self) -> dict[str, Any]:
        return {
            "lam": self.lam,
            "gain": self.gain,
            "lam_max": self.lam_max,
            "prior_count": self.prior_count,
            "reference": self.reference,
            "calibration_runs": self.calibration_runs,
            "calibration_steps": self.calibration_steps,
        }

    def state_dict(self) -> dict[str, Any]:
        state = super().state_dict()
        state.update(stat_sum=np.copy(self._sum), stat_count=np.copy(self._count))
        state["last_correction"] = self._last.copy()
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        check_state(state, self.name)
        try:  # read everything before anything is assigned: a failed load changes nothing
            stats = [
                np.asarray(state[k], dtype=np.float64).copy()
                for k in ("stat_sum", "stat_count", "last_correction")
            ]
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"state lacks strol-adaptive's statistics ({e})") from None
        total, count, last = stats
        for key, arr in zip(("stat_sum", "stat_count", "last_correction"), stats, strict=True):
            if not np.isfinite(arr).all():
                raise ValueError(f"state[{key!r}] must be finite (no NaN or inf)")
        if (count < 0).any() or (count != np.round(count)).any():
            raise ValueError("state['stat_count'] must hold integers >= 0 (counts of corrections)")
        if (np.abs(total) > count * (1 + 1e-9)).any():
            raise ValueError(
                "state['stat_sum'] must lie in [-stat_count, stat_count] (a sum of cosines)"
            )
        theta_rows = np.shape(np.asarray(state.get("theta")))[:-1]
        if (
            total.shape != count.shape
            or total.shape != theta_rows
            or last.shape
            != (
                *theta_rows,
                self.task.dim,
            )
        ):
            raise ValueError(
                f"state's statistics must match θ̂'s batch {theta_rows}: stat_sum {total.shape}, "
                f"stat_count {count.shape}, last_correction {last.shape}"
            )
        super().load_state_dict(state)
        self._sum, self._count, self._last = stats
