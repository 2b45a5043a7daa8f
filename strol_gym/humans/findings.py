"""Correction models grounded in published findings about people (the zoo's second shelf).

The zoo of ``strol_gym.humans.zoo`` changes the eq. M6 teacher in one respect each, chosen by
the designer. The models here take their respect from a measured or published behaviour:

- ``competence`` (Wang et al., arXiv 2501.03515, N = 60): people *withhold* necessary corrections
  from a robot that does badly and *add* unnecessary ones to a robot that does well;
- ``margin-noise`` (Li et al., arXiv 2601.01904, "trajectory similarity noise"; B-Pref's
  "equal" teacher, Lee et al. 2021): errors grow when the options are close in θ*-reward, and
  below a margin the person is indifferent;
- ``hazard``: a state-dependent timing hazard (the issue cites arXiv 2602.18603): whether a
  person steps in at a step depends on how wrong the robot's motion looks there;
- ``scale-free``: the Boltzmann person with β set against the spread of the candidates'
  θ*-reward, so one β means the same in every Task (``boltzmann``'s β multiplies raw θ*·g,
  whose size differs by Task and by state);
- B-Pref's scripted teachers (Lee et al., NeurIPS 2021 Datasets & Benchmarks) as correction
  analogues: ``bpref-stoc`` (β = 1), ``bpref-mistake`` (ε = 0.1), ``bpref-skip`` (0.1),
  ``bpref-equal`` (0.1). ``bpref-myopic`` is left out: its γ = 0.9 weights a segment's later
  steps more than its earlier ones, and one correction is one step, so there is nothing for γ
  to weigh (the myopic person of the zoo is a different idea: no look-ahead).

All of them read one situational number, the **margin** of a correction (:func:`margin`):
with R(c) = θ*·g(x, c, u_R) over the person's candidates c (the zero correction among them,
R = 0), m = max_c R(c) / (max_c R(c) − min_c R(c)) ∈ [0, 1]: how much the best correction
gains over none, relative to how much the candidates differ. m ≈ 0 when the robot's own motion
is already about the best there is (a competent robot, nothing to gain), m ≈ 1 when almost any
correction improves on it (a robot doing badly). It uses only what the person sees (x, u_R, the
admissible corrections) and θ*, never θ̂. Each model keeps the interface's promises (same draws
whatever θ̂; a silent correction is u_H = 0 exactly). ``strol-bench fit-human`` fits each of
them (``strol_gym.benchmarks.sessions.fitting``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from strol_gym.humans.aim import AimedModel, FittedAimedModel
from strol_gym.humans.builtin import NominalModel
from strol_gym.humans.checks import check_fraction
from strol_gym.humans.choices import perturb
from strol_gym.humans.interface import DEFAULT_CANDIDATES, HumanModel, Replayed, SimulatedHuman
from strol_gym.humans.zoo import SkippingModel, _silence, check_probability
from strol_gym.tasks.base import Task

MAX_RELATIVE_BETA = 1e4
"""The largest scale-free β: logits differ by at most β between the best and worst candidate."""


def candidate_rewards(
    task: Task, x: np.ndarray, u_r: np.ndarray, theta: np.ndarray, candidates: np.ndarray
) -> np.ndarray:
    """R (n, K) = θ·g(x, c, u_R) for each person's candidates c (n, K, a)."""
    g = task.g(x[:, None, :], candidates, u_r[:, None, :])
    return np.einsum("nkd,nd->nk", g, theta)


def margin(rewards: np.ndarray) -> np.ndarray:
    """m (n,) = max R / (max R − min R) with the zero correction's R = 0 among the options;
    0 where all candidates tie (see the module docstring)."""
    top = np.maximum(rewards.max(axis=1), 0.0)
    spread = top - np.minimum(rewards.min(axis=1), 0.0)
    return np.divide(top, spread, out=np.zeros_like(top), where=spread > 0)


def check_positive(name: str, value: Any, high: float) -> float:
    """A number in [0, high], else ValueError naming it."""
    rng = f"a number in [0, {high:g}]"
    try:
        v = math.nan if isinstance(value, bool | np.bool_) else float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and 0.0 <= v <= high):
        raise ValueError(f"{name} must be {rng}, got {value!r}")
    return v


class MarginSilenceModel(NominalModel):
    """The eq. M6 teacher who corrects only with a probability ``p_correct(m)`` of the
    correction's margin m (module docstring), else gives none (u_H = 0): the one choice block
    of ``competence`` and ``hazard``, which differ only in p_correct. One uniform draw per
    correction."""

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        return {"act": rng.random(n)}

    def p_correct(self, m: np.ndarray) -> np.ndarray:
        """P(correct) at margin m (each model's own)."""
        raise NotImplementedError

    def corrections(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        u = super().corrections(x, u_r, theta_star, draws, theta_hat, k)
        pref = self.preference(theta_star, k)
        m = margin(candidate_rewards(self.task, x, u_r, pref, draws.candidates))
        return _silence(u, draws.extra["act"] >= self.p_correct(m))


class CompetenceModel(MarginSilenceModel):
    """Competence-dependent propensity (arXiv 2501.03515): the eq. M6 teacher who corrects with
    probability p(m) = p_good + (p_bad − p_good)·m, where m is the correction's margin (module
    docstring: 0 when the robot's motion is already about the best, 1 when it does badly), and
    otherwise gives none (u_H = 0). With the defaults p_good = 0.9 > p_bad = 0.5 the person adds
    corrections where little is to gain and withholds half of those a bad robot needs, as the
    study found (withholding p < 0.0001, unnecessary corrections p = 0.017). One uniform draw per
    correction. Parameters: σ, ε, ``p_good``, ``p_bad`` (probabilities), ``n_candidates``.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        p_good: float = 0.9,
        p_bad: float = 0.5,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.p_good = check_probability("p_good", p_good)
        self.p_bad = check_probability("p_bad", p_bad)

    def p_correct(self, m: np.ndarray) -> np.ndarray:
        """P(correct) at margin m."""
        return self.p_good + (self.p_bad - self.p_good) * m

    propensity = p_correct


class HazardModel(MarginSilenceModel):
    """A state-dependent timing hazard (issue 35 cites arXiv 2602.18603): at each step the
    person steps in with probability h = 1 − exp(−λ·exp(γ (m − 1))), a proportional hazard in
    the margin m (module docstring), else lets the robot be (u_H = 0). λ is the hazard where the
    robot does worst (m = 1), γ how sharply it falls where the robot does well: with the defaults
    λ = 1, γ = 3 a person steps in 63 % of the time at m = 1 and 5 % at m = 0. When they step in
    they correct as the eq. M6 teacher. One uniform draw per step. Parameters: σ, ε, ``rate`` = λ
    (≥ 0), ``gamma`` = γ (≥ 0), ``n_candidates``.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        rate: float = 1.0,
        gamma: float = 3.0,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.rate = check_positive("rate", rate, 100.0)
        self.gamma = check_positive("gamma", gamma, 100.0)

    def p_correct(self, m: np.ndarray) -> np.ndarray:
        """P(step in) at margin m."""
        return -np.expm1(-self.rate * np.exp(self.gamma * (m - 1.0)))

    hazard = p_correct


class MarginNoiseModel(NominalModel):
    """Margin-dependent noise and indifference (arXiv 2601.01904's similarity noise; B-Pref's
    "equal"): the eq. M6 teacher whose hand is noisier the smaller the margin m (module
    docstring), σ_m = σ + κ (1 − m), and who gives no correction (u_H = 0) when m < ``equal``:
    the options look alike, as B-Pref's equal teacher labels two segments equal when their
    returns differ by less than a fraction of the typical return. Parameters: σ, ε, ``kappa``
    = κ (in units of a_max, default 0.25), ``equal`` ∈ [0, 1] (default 0.1), ``n_candidates``.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        kappa: float = 0.25,
        equal: float = 0.1,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.kappa = check_fraction("kappa", kappa)
        self.equal = check_probability("equal", equal)

    def corrections(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        if theta_hat is None:
            raise ValueError(f"{type(self).__name__} teaches relative to θ̂: pass theta_hat")
        pref = self.preference(theta_star, k)
        u = self.choose(x, u_r, pref, draws, theta_hat, k)
        m = margin(candidate_rewards(self.task, x, u_r, pref, draws.candidates))
        sigma = (self.sigma + self.kappa * (1.0 - m))[:, None]
        u = perturb(self.task, u, sigma, self.bias, Replayed(draws.noise))
        return _silence(u, m < self.equal)


class ScaleFreeBoltzmannModel(HumanModel):
    """The Boltzmann person with a scale-free β: P(c) ∝ exp(β R(c) / S) over the candidates,
    R(c) = θ*·g(x, c, u_R), S = max R − min R (the candidates' spread, zero included), then δ.
    β is the log-odds of the best candidate against the worst, whatever the Task or the state
    (``boltzmann``'s β multiplies raw θ*·g, whose size is the Task's). Ignores θ̂. Parameters:
    σ, ε, ``beta_rel`` = β (in [0, 1e4], default 10), ``n_candidates``.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        beta_rel: float = 10.0,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.beta_rel = check_positive("beta_rel", beta_rel, MAX_RELATIVE_BETA)

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        return {"pick": rng.random((n, 1))}

    def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        logits = scale_free_logits(
            candidate_rewards(self.task, x, u_r, theta_star, draws.candidates), self.beta_rel
        )
        p = np.exp(logits - logits.max(axis=1, keepdims=True))
        p /= p.sum(axis=1, keepdims=True)
        idx = np.minimum((p.cumsum(axis=1) < draws.extra["pick"]).sum(axis=1), p.shape[1] - 1)
        return draws.candidates[np.arange(len(idx)), idx]


def scale_free_logits(rewards: np.ndarray, beta_rel: float) -> np.ndarray:
    """β R / S per candidate (S the spread of R over a person's candidates and zero)."""
    spread = np.maximum(rewards.max(axis=1), 0.0) - np.minimum(rewards.min(axis=1), 0.0)
    scale = np.divide(beta_rel, spread, out=np.zeros_like(spread), where=spread > 0)
    return rewards * scale[:, None]


class ReversingModel(NominalModel):
    """B-Pref's "mistake" as a correction: with probability ``rate`` the person pushes the
    opposite way to the teacher's correction, u = −u*, else u = u*; then δ. A flipped label
    of a preference is the reverse of what the teacher wants, and so is the reversed push.
    One uniform draw per correction. Parameters: σ, ε, ``rate`` (default 0.1), ``n_candidates``.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        rate: float = 0.1,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.rate = check_probability("rate", rate)

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        return {"flip": rng.random(n)}

    def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        u = super().choose(x, u_r, theta_star, draws, theta_hat, k)
        return np.where((draws.extra["flip"] < self.rate)[:, None], -u, u)


class BPrefStocModel(ScaleFreeBoltzmannModel):
    """B-Pref's "stoc" teacher (β = 1) as a correction: the scale-free Boltzmann person with
    β = 1, i.e. the best candidate only e times as likely as the worst: a very noisy chooser.
    Parameters as ``scale-free`` (default ``beta_rel`` 1)."""

    def __init__(self, task, sigma=0.0, bias=0.0, beta_rel=1.0, n_candidates=DEFAULT_CANDIDATES):
        super().__init__(task, sigma, bias, beta_rel, n_candidates)


class BPrefMistakeModel(ReversingModel):
    """B-Pref's "mistake" teacher (ε = 0.1): ``reversing`` with ``rate`` 0.1 (its default)."""


class BPrefSkipModel(SkippingModel):
    """B-Pref's "skip" teacher (0.1) as a correction: ``skipping`` with p = 0.1. B-Pref skips
    a query when neither segment's return reaches a threshold (an irrelevant query); one
    correction has no second segment, so the analogue is a person who does not answer one
    correction in ten, whatever the state (the state-dependent silence is ``bpref-equal``)."""

    def __init__(self, task, sigma=0.0, bias=0.0, p=0.1, n_candidates=DEFAULT_CANDIDATES):
        super().__init__(task, sigma, bias, p, n_candidates)


class BPrefEqualModel(MarginNoiseModel):
    """B-Pref's "equal" teacher (0.1) as a correction: ``margin-noise`` with no extra noise
    (κ = 0) and indifference below the margin 0.1: no correction where the best gains less than
    a tenth of the candidates' spread of θ*-reward."""

    def __init__(
        self, task, sigma=0.0, bias=0.0, kappa=0.0, equal=0.1, n_candidates=DEFAULT_CANDIDATES
    ):
        super().__init__(task, sigma, bias, kappa, equal, n_candidates)


FITTED_STUDY: dict[str, Any] = {
    "model": "scale-free",
    "params": {"sigma": 0.490, "bias": 0.050, "beta_rel": 8.02},
    "per_task": {
        "study-task1": {
            "sigma": [0.552, 0.439, 0.693],
            "bias": [-0.029, -0.232, 0.174],
            "beta_rel": [6.80, 3.88, 11.92],
            "heldout_loglik": 375.1,
        },
        "study-task2": {
            "sigma": [0.451, 0.367, 0.554],
            "bias": [0.121, 0.002, 0.239],
            "beta_rel": [9.13, 6.32, 13.18],
            "heldout_loglik": 863.6,
        },
        "study-task3": {
            "sigma": [0.467, 0.372, 0.586],
            "bias": [0.057, -0.018, 0.132],
            "beta_rel": [8.13, 5.48, 12.07],
            "heldout_loglik": 872.4,
        },
    },
    "source": "the authors' user study (github VT-Collab/StROL_RAL, data removed at d383bef): "
    "12 participants × 3 Tasks × 3 learners, imported with strol-bench import-study (issue 32, "
    "one update per correction, θ̂0 not logged)",
    "command": "strol-bench fit-human OUT/user_*_task_J_*.jsonl --human scale-free "
    "--compare boltzmann,myopic --folds 4 --out DIR (J = 1, 2, 3; sandwich intervals with the "
    "leave-one-person-out covariance)",
    "date": "2026-11-25",
}
"""The fit behind ``fitted-study`` (docs/humans.md, "Fitted to the twelve people"): per Task the
estimate and its 95 % interval over people [estimate, low, high] (the person-clustered
sandwich); ``params`` the mean of the three Tasks' estimates (σ, ε in units of a_max)."""


class FittedStudyModel(ScaleFreeBoltzmannModel):
    """The people of the authors' user study as fitted (``FITTED_STUDY``): the scale-free
    Boltzmann person, the best of the θ̂-free models by held-out log-likelihood over folds of
    participants (pooled over the three Tasks: scale-free 2111.1, Boltzmann 2103.2, myopic
    1883.4; scale-free best in Tasks 2 and 3, Boltzmann in Task 1), with the mean of the Tasks'
    estimates: β = 8.0 (log-odds of the best candidate over the worst), σ = 0.49, ε = 0.05.
    The eq. M6 teacher and its zoo need θ̂, reconstructed only for the One and MOF sessions:
    there the teacher fits worst and the teacher scaled down (``under``) best (docs/humans.md).
    In ``strol-bench robustness`` σ and ε are the grid's, as for every human; β is the fit's.
    Parameters as ``scale-free``."""

    def __init__(
        self,
        task: Task,
        sigma: float = FITTED_STUDY["params"]["sigma"],
        bias: float = FITTED_STUDY["params"]["bias"],
        beta_rel: float = FITTED_STUDY["params"]["beta_rel"],
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, beta_rel, n_candidates)


FINDINGS: dict[str, type[HumanModel]] = {
    "competence": CompetenceModel,
    "margin-noise": MarginNoiseModel,
    "hazard": HazardModel,
    "scale-free": ScaleFreeBoltzmannModel,
    "reversing": ReversingModel,
    "bpref-stoc": BPrefStocModel,
    "bpref-mistake": BPrefMistakeModel,
    "bpref-skip": BPrefSkipModel,
    "bpref-equal": BPrefEqualModel,
    "fitted-study": FittedStudyModel,
    "aimed": AimedModel,
    "fitted-aimed": FittedAimedModel,
}
"""The models of this module by name, registered on import of ``strol_gym.humans``."""

CompetenceHuman = SimulatedHuman.of(CompetenceModel, "CompetenceHuman")
HazardHuman = SimulatedHuman.of(HazardModel, "HazardHuman")
MarginNoiseHuman = SimulatedHuman.of(MarginNoiseModel, "MarginNoiseHuman")
ScaleFreeBoltzmannHuman = SimulatedHuman.of(ScaleFreeBoltzmannModel, "ScaleFreeBoltzmannHuman")
ReversingHuman = SimulatedHuman.of(ReversingModel, "ReversingHuman")


def register_findings() -> None:
    """Register every model of :data:`FINDINGS` as a shipped human (idempotent)."""
    from strol_gym.humans.registry import HUMANS

    for name, model in FINDINGS.items():
        if name not in HUMANS.names():
            HUMANS.register(name, model, builtin=True)


__all__ = [
    "FINDINGS",
    "FITTED_STUDY",
    "BPrefEqualModel",
    "BPrefMistakeModel",
    "BPrefSkipModel",
    "BPrefStocModel",
    "CompetenceModel",
    "FittedStudyModel",
    "HazardModel",
    "MarginNoiseModel",
    "MarginSilenceModel",
    "ReversingModel",
    "ScaleFreeBoltzmannModel",
    "candidate_rewards",
    "margin",
    "register_findings",
    "scale_free_logits",
]
