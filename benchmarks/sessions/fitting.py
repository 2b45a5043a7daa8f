"""Fitting human models to correction logs: the likelihood of each model, its maximum, the
intervals over people and the held-out comparison (``strol-bench fit-human`` is the front
end).

**What a fit sees.** A :class:`Corrections` holds only what a real person's log holds: per
correction the state x, u_H, u_R, θ* (the preference the person was asked to teach), θ̂ before
the correction where it is logged, the correction's index in its episode and who made it. Never
the simulator's candidates, noise draws, seeds or the header's generating parameters (σ, the
human's name): stripping them from a log gives the same estimate (a test checks).

**The likelihood.** Each model is a :class:`Family`: per correction a mixture of noise-free
choices μ_c with weights w_c (one choice for a deterministic model), a probability q of giving
no correction (u_H = 0 exactly) and a noise scale σ_i, so that

    p(u_H) = q                                          if u_H = 0 and q > 0,
           = (1 − q) Σ_c w_c Π_j f(u_Hj; s μ_cj + ε a_j, σ_i a_j)   otherwise,

with f the Gaussian density, replaced by its tail mass P(u ≥ a_j) or P(u ≤ −a_j) for a
component that sits exactly on the action bound (a log that clips records the bound: a censored
Gaussian). The simulated people choose among k random candidates (and zero) that no log holds,
so their choice is itself random, and the likelihood integrates over it on a fixed quadrature
(``QUADRATURE`` scrambled-Sobol points over the admissible box plus zero, seeded):

- a choice that minimises a cost (the eq. M6 teacher, the myopic person) has the order
  statistic of k uniform draws: a point whose cost beats a fraction F of the box carries
  (k/Q)(1 − F)^(k−1), zero carries (1 − F(0))^k (:func:`order_weights`); k is the simulated
  person's candidate count (512): for a real person, how many options they weigh;
- a Boltzmann choice carries exp(β R(c)) at each point, k/Q candidates per point;
- the wrong θ of ``mistaken`` is integrated over ``WRONG_THETAS`` draws of the Task's prior.

Every parameter is estimated by maximum likelihood (L-BFGS-B on a transformed scale, several
starts); the 95 % intervals have the person as the unit (:data:`INTERVALS`: a person-clustered
sandwich by default, or a bootstrap resampling each person's corrections together); the
held-out log-likelihood sums, over folds of people, the log-likelihood of the held-out people
under the fit to the others; ``--compare`` picks one model by :data:`PARSIMONY_RULE`
(:func:`select`). Models whose choice needs θ̂ are fitted only to corrections whose
θ̂ the log holds (or reconstructs: :attr:`Corrections.theta_hat_source`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
from scipy import optimize, special
from scipy.stats import qmc

from strol_gym.humans.aim import (
    AIM_PARAMS,
    MAX_AIM,
    MAX_TURN,
    MIN_AIM,
    TURN_AXES,
    aim_direction,
    aimed_corrections,
    emphasis_names,
    steepest_ascent,
)
from strol_gym.humans.aim import log_density as aim_log_density
from strol_gym.humans.findings import margin, scale_free_logits
from strol_gym.humans.interface import DEFAULT_CANDIDATES
from strol_gym.tasks.base import Task

QUADRATURE = 4096
"""Quadrature points over the admissible box (plus zero): 8 per candidate of the simulated
person's 512, so that the order statistic's few best points are resolved."""
BOLTZMANN_QUADRATURE = 1024
"""Quadrature points for a Boltzmann choice, whose weight spreads over the box (no order
statistic to resolve): each stands for k/Q of the person's candidates."""
TOP = 256
"""Points kept per correction for a cost-minimising choice: its weight falls as
exp(−k·rank/Q), e^−32 at the 256th point."""
WRONG_THETAS = 32
"""Prior draws integrating the wrong θ of ``mistaken``."""
FIT_SEED = 20_260_001
"""The seed of the fitter's own quadrature and prior draws (fixed: one dataset, one estimate)."""
SOFT_EQUAL = 0.02
"""The width over which the fitter smooths ``margin-noise``'s hard indifference threshold (the
person's candidates are not logged, so their margin and the fitter's differ slightly)."""
MAX_CORRECTIONS = 1_000_000
"""The most corrections a fit reads (sizes capped)."""


# ---------------------------------------------------------------------------- the data
@dataclasses.dataclass
class Corrections:
    """Corrections as a real log holds them (module docstring). ``person`` indexes ``people``;
    ``theta_hat`` rows are NaN where θ̂ is unknown."""

    task: Task
    x: np.ndarray
    u_h: np.ndarray
    u_r: np.ndarray
    theta_star: np.ndarray
    theta_hat: np.ndarray
    k: np.ndarray
    episode: np.ndarray
    person: np.ndarray
    people: list[str]
    theta_hat_source: str = "logged"

    def __len__(self) -> int:
        return len(self.x)

    @property
    def has_theta_hat(self) -> np.ndarray:
        return np.isfinite(self.theta_hat).all(axis=1)

    def subset(self, rows: np.ndarray) -> Corrections:
        """The corrections ``rows`` (an index or mask array), people renumbered densely."""
        rows = np.asarray(rows)
        keep = np.unique(self.person[rows])
        remap = np.full(len(self.people), -1)
        remap[keep] = np.arange(len(keep))
        return dataclasses.replace(
            self,
            x=self.x[rows],
            u_h=self.u_h[rows],
            u_r=self.u_r[rows],
            theta_star=self.theta_star[rows],
            theta_hat=self.theta_hat[rows],
            k=self.k[rows],
            episode=self.episode[rows],
            person=remap[self.person[rows]],
            people=[self.people[i] for i in keep],
        )


def person_rows(data: Corrections) -> list[np.ndarray]:
    """The row indices of each person, in ``data.people`` order."""
    order = np.argsort(data.person, kind="stable")
    cuts = np.searchsorted(data.person[order], np.arange(1, len(data.people)))
    return np.split(order, cuts)


# ---------------------------------------------------------------------------- quadrature
def quadrature(task: Task, points: int = QUADRATURE) -> np.ndarray:
    """(points + 1, a): the zero correction first, then a scrambled Sobol sequence over the
    admissible box (seeded: one dataset, one estimate)."""
    a = task.action_dim
    pts = qmc.Sobol(a, scramble=True, seed=FIT_SEED).random(points)
    bound = np.asarray(task.action_bound, dtype=np.float64)
    return np.concatenate([np.zeros((1, a)), (2.0 * pts - 1.0) * bound])


def _chunks(n: int, per_row: int, budget: int = 4_000_000) -> list[slice]:
    step = max(1, budget // max(1, per_row))
    return [slice(i, min(n, i + step)) for i in range(0, n, step)]


def quadrature_g(data: Corrections, q: np.ndarray) -> np.ndarray:
    """g(x, c, u_R) (n, Q, d) at every quadrature point c of every correction."""
    task = data.task
    out = np.empty((len(data), len(q), task.dim))
    for rows in _chunks(len(data), len(q) * (task.state_dim + task.dim)):
        out[rows] = task.g(data.x[rows][:, None], q[None], data.u_r[rows][:, None])
    return out


def teacher_objective(data: Corrections, g: np.ndarray, target: np.ndarray) -> np.ndarray:
    """‖target − (θ̂ + α g)‖² (n, Q): what eq. M6 minimises, at each quadrature point."""
    diff = (target - data.theta_hat)[:, None, :] - data.task.alpha * g
    return np.einsum("nqd,nqd->nq", diff, diff)


def order_weights(cost: np.ndarray, k: int) -> np.ndarray:
    """log P (n, Q) that the best of the zero correction and ``k`` uniform candidates (the
    simulated person's) lies at each quadrature point, for a choice minimising ``cost``.

    With F the fraction of the box whose cost is below a point's (its rank among the
    quadrature points): P(zero) = (1 − F(zero))^k, and a point c better than zero carries
    (k/Q)(1 − F_c)^(k−1): the order statistic of k uniform draws."""
    m = cost.shape[1] - 1
    inner = cost[:, 1:]
    order = np.argsort(inner, axis=1, kind="stable")
    ranks = np.empty_like(order)
    np.put_along_axis(ranks, order, np.arange(m)[None, :], axis=1)
    f = (ranks + 0.5) / m
    better = inner < cost[:, :1]
    f0 = better.mean(axis=1)
    out = np.empty_like(cost)
    with np.errstate(divide="ignore"):
        out[:, 0] = k * np.log1p(-np.minimum(f0, 1.0))
        out[:, 1:] = np.where(better, math.log(k / m) + (k - 1) * np.log1p(-f), -np.inf)
    return out - special.logsumexp(out, axis=1, keepdims=True)


def top(logw: np.ndarray, q: np.ndarray, n_top: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``n_top`` heaviest quadrature points per correction: (points (n, T, a), log weights
    (n, T) renormalised). The order statistic's weight falls as exp(−k·rank/Q), so the rest
    carry nothing a float can hold."""
    n_top = min(n_top, logw.shape[1])
    idx = np.argpartition(-logw, n_top - 1, axis=1)[:, :n_top]
    lw = np.take_along_axis(logw, idx, axis=1)
    return q[idx], lw - special.logsumexp(lw, axis=1, keepdims=True)


def best_point(data: Corrections, cost: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The quadrature point of least ``cost`` per correction (n, a)."""
    return q[np.argmin(cost, axis=1)]


def teacher_choice(data: Corrections) -> np.ndarray:
    """u*: eq. M6's best correction among the quadrature points (n, a), from the logged θ̂."""
    q = quadrature(data.task)
    return best_point(data, teacher_objective(data, quadrature_g(data, q), data.theta_star), q)


def best_for_theta(data: Corrections) -> np.ndarray:
    """θ*'s best single correction, argmax θ*·g over the quadrature points (n, a)."""
    q = quadrature(data.task)
    rew = np.einsum("nqd,nd->nq", quadrature_g(data, q), data.theta_star)
    return best_point(data, -rew, q)


# ---------------------------------------------------------------------------- parameters
@dataclasses.dataclass(frozen=True)
class Param:
    """One fitted parameter: its range [low, high] (mapped through a logistic, or a log for
    a scale) and a starting value."""

    name: str
    low: float
    high: float
    start: float
    log: bool = False

    def to_free(self, v: float) -> float:
        if self.log:
            return math.log(min(max(v, self.low), self.high))
        p = (v - self.low) / (self.high - self.low)
        p = min(max(p, 1e-9), 1 - 1e-9)
        return math.log(p / (1 - p))

    def from_free(self, t: float) -> float:
        if self.log:
            return float(min(max(math.exp(t), self.low), self.high))
        return float(self.low + (self.high - self.low) * special.expit(t))


SIGMA = Param("sigma", 1e-3, 10.0, 0.3, log=True)
BIAS = Param("bias", -2.0, 2.0, 0.0)


@dataclasses.dataclass
class Parts:
    """A family's likelihood pieces at one parameter value (module docstring): choices μ
    (n or 1, C, a) in units of a_max, log weights (n, C), noise σ (n,) or (n, C) in units of
    a_max, bias ε, log q (n,) or None for a person who always corrects; ``fixed``: μ does not
    depend on the parameters (its distances to u_H are cached)."""

    mu: np.ndarray
    logw: np.ndarray
    sigma: np.ndarray
    bias: float
    log_q: np.ndarray | None = None
    fixed: bool = True


def _unit(data: Corrections, u: np.ndarray) -> np.ndarray:
    return u / np.asarray(data.task.action_bound, dtype=np.float64)


class Family:
    """A fittable model: ``prepare`` computes what does not depend on the parameters (the
    choice's weights over the quadrature), ``parts`` the likelihood's pieces at a value."""

    name = ""
    params: tuple[Param, ...] = (SIGMA, BIAS)
    needs_theta_hat = False
    n_candidates = DEFAULT_CANDIDATES
    """The simulated person's candidate count k (the order statistic's)."""
    reduces_to: tuple[str, dict[str, float]] | None = None
    """(simpler model, parameter values) at which this model is exactly the simpler one (e.g.
    ``mistaken`` at rate 0 is ``nominal``): the parsimony rule's nesting (:func:`select`)."""

    def derive(self, v: dict[str, float]) -> dict[str, float]:
        """The model's parameters that the fit does not estimate directly, as functions of the
        fitted ones (``margin-noise``'s κ); reported with delta-method or bootstrap intervals."""
        return {}

    def prepare(self, data: Corrections) -> dict[str, Any]:
        raise NotImplementedError

    def parts(self, prep: dict[str, Any], v: dict[str, float]) -> Parts:
        raise NotImplementedError

    def terms(self, prep: dict[str, Any], v: dict[str, float]) -> np.ndarray | None:
        """Each correction's log-likelihood (n,) in units of a_max, for a family whose density
        is not a mixture of Gaussians about choices (``aimed``); None: ``parts`` describes it."""
        return None

    def sample(
        self, prep: dict[str, Any], v: dict[str, float], rng: np.random.Generator
    ) -> np.ndarray | None:
        """A posterior-predictive draw (n, a) in units of a_max for a family with its own
        ``terms``; None: ``simulate`` draws from ``parts``."""
        return None

    def _sigma(self, prep: dict[str, Any], v: dict[str, float]) -> np.ndarray:
        return np.full(len(prep["uh"]), v["sigma"])


class Teacher(Family):
    """The eq. M6 teacher: the best of k uniform candidates and zero, then δ."""

    name, needs_theta_hat = "nominal", True

    def cost(self, data: Corrections, g: np.ndarray, target: np.ndarray) -> np.ndarray:
        return teacher_objective(data, g, target)

    def prepare(self, data):
        q = quadrature(data.task)
        g = quadrature_g(data, q)
        lw = order_weights(self.cost(data, g, data.theta_star), self.n_candidates)
        mu, logw = top(lw, _unit(data, q), TOP)
        return {"uh": _unit(data, data.u_h), "mu": mu, "logw": logw, "g": g, "lw_full": lw}

    def scale(self, v: dict[str, float]) -> float:
        return 1.0

    def parts(self, prep, v):
        s = self.scale(v)
        mu = prep["mu"] if s == 1.0 else prep["mu"] * s
        return Parts(mu, prep["logw"], self._sigma(prep, v), v["bias"], fixed=s == 1.0)


class Myopic(Teacher):
    """The myopic person: the best of k candidates by θ*·g (θ*·φ of the next state)."""

    name, needs_theta_hat = "myopic", False

    def cost(self, data, g, target):
        return -np.einsum("nqd,nd->nq", g, target)


class Scaled(Teacher):
    """over/under: u = s·u* + δ, s in the preset's range."""

    def __init__(self, name: str, low: float, high: float, start: float) -> None:
        self.name = name
        self.params = (SIGMA, BIAS, Param("scale", low, high, start))
        self.reduces_to = ("nominal", {"scale": 1.0})

    def scale(self, v):
        return v["scale"]


class FeatureNoise(Teacher):
    """σ_c = σ + κ r_c, r_c the chosen candidate's ‖g/s‖ over the largest (``noise_with="g"``)."""

    name = "feature-noise"
    params = (SIGMA, BIAS, Param("kappa", 0.0, 5.0, 0.3))
    reduces_to = ("nominal", {"kappa": 0.0})

    def prepare(self, data):
        prep = super().prepare(data)
        scale = np.asarray(data.task.feature_scale, dtype=np.float64)
        size = np.linalg.norm(prep["g"] / scale, axis=-1)  # (n, Q)
        top_size = size.max(axis=1, keepdims=True)
        q = _unit(data, quadrature(data.task))
        # the size at each kept point: find it again by matching the kept points' indices
        idx = np.argpartition(-prep["lw_full"], min(TOP, q.shape[0]) - 1, axis=1)[:, :TOP]
        r = np.take_along_axis(size, idx, axis=1)
        prep["r"] = np.divide(r, top_size, out=np.zeros_like(r), where=top_size > 0)
        return prep

    def _sigma(self, prep, v):
        return v["sigma"] + v["kappa"] * prep["r"]


class Silent(Teacher):
    """The teacher with a probability of no correction (``log_q``) read off the margin."""

    def prepare(self, data):
        prep = super().prepare(data)
        prep["m"] = margin(np.einsum("nqd,nd->nq", prep["g"], data.theta_star))
        return prep

    def log_q(self, prep: dict[str, Any], v: dict[str, float]) -> np.ndarray:
        raise NotImplementedError

    def parts(self, prep, v):
        p = super().parts(prep, v)
        p.log_q = self.log_q(prep, v)
        return p


class Skipping(Silent):
    name = "skipping"
    reduces_to = ("nominal", {"p": 0.0})
    params = (SIGMA, BIAS, Param("p", 0.0, 1.0, 0.2))

    def log_q(self, prep, v):
        return np.full(len(prep["uh"]), math.log(max(v["p"], 1e-300)))


class Competence(Silent):
    name = "competence"
    reduces_to = ("nominal", {"p_good": 1.0, "p_bad": 1.0})
    params = (SIGMA, BIAS, Param("p_good", 0.0, 1.0, 0.8), Param("p_bad", 0.0, 1.0, 0.6))

    def log_q(self, prep, v):
        act = v["p_good"] + (v["p_bad"] - v["p_good"]) * prep["m"]
        return np.log(np.clip(1.0 - act, 1e-300, 1.0))


class Hazard(Silent):
    name = "hazard"
    params = (
        SIGMA,
        BIAS,
        Param("rate", 1e-3, 100.0, 1.0, log=True),
        Param("gamma", 0.0, 20.0, 1.0),
    )

    def log_q(self, prep, v):
        return -v["rate"] * np.exp(v["gamma"] * (prep["m"] - 1.0))


class MarginNoise(Silent):
    """Fitted as the noise at margin 1, σ (the model's own), and at margin 0, ``sigma0`` = σ + κ,
    both on a log scale: σ_m = σ·m + σ0·(1 − m). Derived: the model's κ = σ0 − σ, which may come
    out negative (noise that falls where the options look alike, which the simulated person
    cannot do), and ``sigma_half``, the noise at margin ½. People speak at margins between
    ``equal`` and about 0.6 (in the Robot Task), so σ and σ0 are extrapolations with wide
    intervals, while the noise in between is well determined. Fitting κ ≥ 0 itself put κ̂ at its
    bound 0 in 5 of 20 recovery datasets, where σ's interval was then computed as if κ were
    known, and missed (docs/humans.md, "Recovery")."""

    name = "margin-noise"
    params = (
        SIGMA,
        BIAS,
        Param("sigma0", 1e-3, 10.0, 0.4, log=True),
        Param("equal", 0.0, 1.0, 0.05),
    )

    def _sigma(self, prep, v):
        return v["sigma"] * prep["m"] + v["sigma0"] * (1.0 - prep["m"])

    def derive(self, v):
        return {"kappa": v["sigma0"] - v["sigma"], "sigma_half": 0.5 * (v["sigma"] + v["sigma0"])}

    def log_q(self, prep, v):
        return special.log_expit((v["equal"] - prep["m"]) / SOFT_EQUAL)


def _mix(rate: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    r = min(max(rate, 1e-300), 1.0 - 1e-16)
    return np.concatenate([math.log1p(-r) + a, math.log(r) + b], axis=1)


class Mistaken(Teacher):
    """With probability ``rate`` the teacher's choice toward a wrong θ from the prior."""

    name = "mistaken"
    params = (SIGMA, BIAS, Param("rate", 0.0, 1.0, 0.1))
    reduces_to = ("nominal", {"rate": 0.0})

    def prepare(self, data):
        prep = super().prepare(data)
        rng = np.random.default_rng(FIT_SEED + 2)
        wrong = data.task.prior.sample(rng, WRONG_THETAS)
        lws = [
            order_weights(
                self.cost(data, prep["g"], np.broadcast_to(w, data.theta_star.shape)),
                self.n_candidates,
            )
            for w in wrong
        ]
        mean = special.logsumexp(np.stack(lws), axis=0) - math.log(len(lws))
        mu_w, lw_w = top(mean, _unit(data, quadrature(data.task)), TOP)
        prep["mu"] = np.concatenate([prep["mu"], mu_w], axis=1)
        prep["lw_right"], prep["lw_wrong"] = prep["logw"], lw_w
        return prep

    def parts(self, prep, v):
        logw = _mix(v["rate"], prep["lw_right"], prep["lw_wrong"])
        return Parts(prep["mu"], logw, self._sigma(prep, v), v["bias"])


class Reversing(Teacher):
    """With probability ``rate`` the teacher's correction reversed (B-Pref's mistake)."""

    name = "reversing"
    params = (SIGMA, BIAS, Param("rate", 0.0, 1.0, 0.1))
    reduces_to = ("nominal", {"rate": 0.0})

    def prepare(self, data):
        prep = super().prepare(data)
        prep["lw_one"] = prep["logw"]
        prep["mu"] = np.concatenate([prep["mu"], -prep["mu"]], axis=1)
        return prep

    def parts(self, prep, v):
        logw = _mix(v["rate"], prep["lw_one"], prep["lw_one"])
        return Parts(prep["mu"], logw, self._sigma(prep, v), v["bias"])


class Boltzmann(Family):
    """P(c) ∝ exp(β R(c)) over k uniform candidates and zero (``relative``: β R / S, the
    scale-free β), integrated over the quadrature: each point stands for k/Q candidates."""

    def __init__(self, name: str, relative: bool) -> None:
        self.name, self.relative = name, relative
        beta = Param(
            "beta_rel" if relative else "beta", 1e-3, 1e4 if relative else 1e6, 5.0, log=True
        )
        self.params = (SIGMA, BIAS, beta)

    def prepare(self, data):
        q = quadrature(data.task, BOLTZMANN_QUADRATURE)
        rew = np.einsum("nqd,nd->nq", quadrature_g(data, q), data.theta_star)
        return {"uh": _unit(data, data.u_h), "mu": _unit(data, q)[None], "R": rew}

    def parts(self, prep, v):
        if self.relative:
            logits = scale_free_logits(prep["R"], v["beta_rel"])
        else:
            logits = v["beta"] * prep["R"]
        logits[:, 1:] += math.log(self.n_candidates / (logits.shape[1] - 1))
        logw = logits - special.logsumexp(logits, axis=1, keepdims=True)
        return Parts(prep["mu"], logw, self._sigma(prep, v), v["bias"])


class Aimed(Family):
    """The aimed person (``strol_gym.humans.aim``): the direction's projected normal about the
    steepest ascent of θ* ⊙ w, the rotation weighed, a log-normal size or two; its density in
    closed form. The emphasis weights w (``w_<feature>``, the first feature's held at 1) are
    the Task's: they join ``params`` when the family meets its corrections (``prepare``), and
    ρ leaves them in a Task without rotation axes (it weighs none there)."""

    name = "aimed"
    base_params: tuple[Param, ...] = (
        Param("aim", MIN_AIM, MAX_AIM, 1.0, log=True),
        Param("turn", 1e-2, MAX_TURN, 0.5, log=True),
        Param("size", 1e-3, 100.0, 1.2, log=True),
        Param("size_sd", 1e-3, 10.0, 0.5, log=True),
        Param("small_share", 0.0, 1.0, 0.2),
        Param("small_size", 1e-3, 100.0, 0.3, log=True),
    )
    params: tuple[Param, ...] = base_params

    def __init__(self) -> None:
        self._directions: dict[tuple[Any, ...], tuple[np.ndarray, np.ndarray]] = {}

    def prepare(self, data):
        task, d = data.task, data.task.dim
        names = emphasis_names(task)
        own = self.base_params
        if task.action_dim <= TURN_AXES:  # no axis for ρ to weigh: not a parameter here
            own = tuple(p for p in own if p.name != "turn")
        self.params = own + tuple(Param(k, 1e-2, 100.0, 1.0, log=True) for k in names)
        one = [
            steepest_ascent(task, data.x, data.u_r, data.theta_star * np.eye(d)[j])
            for j in range(d)
        ]
        return {
            "uh": _unit(data, data.u_h),
            "bests": np.stack(one, axis=1),
            "names": names,
            "x": data.x,
            "u_r": data.u_r,
            "theta_star": data.theta_star,
            "task": task,
        }

    def _split(
        self, prep: dict[str, Any], v: dict[str, float]
    ) -> tuple[np.ndarray, dict[str, float]]:
        """The aimed directions (n, a) for θ* ⊙ w at ``reach`` and the scalar parameters."""
        w = np.array([1.0] + [v.get(k, 1.0) for k in prep["names"]])
        reach = v.get("reach", 0.0)
        if reach <= 0.0:  # the steepest ascent is linear in θ: one sum of the features'
            best = np.einsum("j,nja->na", w, prep["bests"])
        else:  # the ascent, once per (w, reach) and set of corrections (a held ρ, w: once)
            x = prep["x"]
            key = (id(x), tuple(w.tolist()), reach)
            cached = self._directions.get(key)
            if cached is None:
                theta = prep["theta_star"] * w
                best = aim_direction(prep["task"], x, prep["u_r"], theta, reach)
                if len(self._directions) > 64:
                    self._directions.clear()
                self._directions[key] = (x, best)  # x kept: its id stays unique while cached
            else:
                best = cached[1]
        return best, {k: v.get(k, 1.0) for k in AIM_PARAMS}

    def terms(self, prep, v):
        best, own = self._split(prep, v)
        return aim_log_density(prep["uh"], best, **own)

    def sample(self, prep, v, rng):
        best, own = self._split(prep, v)
        n, a = best.shape
        return aimed_corrections(best, rng.standard_normal((n, a + 1)), rng.random(n), **own)


class AimedReach(Aimed):
    """``aimed`` with its ``reach`` fitted too (:func:`strol_gym.humans.aim.aim_direction`: the
    direction of the best push of that length; each evaluation runs the ascent, so it is the
    slower fit)."""

    name = "aimed-reach"
    base_params = (*Aimed.base_params, Param("reach", 1e-2, 10.0, 1.0, log=True))
    params = base_params
    reduces_to = None


class _Preset(Family):
    """A registered preset fitted as its family (its parameters free)."""

    def __init__(self, name: str, family: Family) -> None:
        self.name, self.family = name, family
        self.params, self.needs_theta_hat = family.params, family.needs_theta_hat
        self.reduces_to = family.reduces_to

    def derive(self, v):
        return self.family.derive(v)

    def prepare(self, data):
        return self.family.prepare(data)

    def parts(self, prep, v):
        return self.family.parts(prep, v)

    def terms(self, prep, v):
        return self.family.terms(prep, v)

    def sample(self, prep, v, rng):
        return self.family.sample(prep, v, rng)


def families() -> dict[str, Family]:
    """Every fittable registered human by name (the presets fit their family's parameters)."""
    out: dict[str, Family] = {
        "nominal": Teacher(),
        "boltzmann": Boltzmann("boltzmann", relative=False),
        "myopic": Myopic(),
        "feature-noise": FeatureNoise(),
        "skipping": Skipping(),
        "over": Scaled("over", 1.0, 10.0, 2.0),
        "under": Scaled("under", 1e-3, 1.0, 0.5),
        "mistaken": Mistaken(),
        "competence": Competence(),
        "hazard": Hazard(),
        "margin-noise": MarginNoise(),
        "scale-free": Boltzmann("scale-free", relative=True),
        "reversing": Reversing(),
        "aimed": Aimed(),
        "aimed-reach": AimedReach(),
    }
    for preset, base in (
        ("bpref-stoc", "scale-free"),
        ("bpref-mistake", "reversing"),
        ("bpref-skip", "skipping"),
        ("bpref-equal", "margin-noise"),
        ("fitted-study", "scale-free"),
        ("fitted-aimed", "aimed"),
    ):
        out[preset] = _Preset(preset, out[base])
    return out


NOT_FITTABLE = {
    "changing": "its switch index is a change point that one preference's logs do not identify",
    "early": "its window is a discrete index (fit `skipping` or `hazard` for silences)",
    "late": "its window is a discrete index (fit `skipping` or `hazard` for silences)",
    "driver": "its look-ahead score is not exposed by `choices.driver_correction` (only its "
    "argmax): not yet fittable",
}
"""Registered humans ``fit-human`` leaves out, and why."""


def family(name: str) -> Family:
    """The fittable family of registered human ``name``, else ValueError listing them."""
    table = families()
    if not isinstance(name, str) or name not in table:
        why = NOT_FITTABLE.get(name) if isinstance(name, str) else None
        extra = f" ({why})" if why else ""
        raise ValueError(f"--human {name!r} cannot be fitted{extra}; fittable: {', '.join(table)}")
    return table[name]


# ---------------------------------------------------------------------------- the likelihood
def loglik_terms(fam: Family, prep: dict[str, Any], v: dict[str, float]) -> np.ndarray:
    """Each correction's log-likelihood (n,) under ``fam`` at parameter values ``v``, in
    u_H's own units (the a_max Jacobian included, so that models compare)."""
    own = fam.terms(prep, v)
    if own is not None:
        return own - prep["log_volume"]
    p = fam.parts(prep, v)
    uh = prep["uh"]
    a = uh.shape[1]
    sig = np.maximum(p.sigma, 1e-9)
    sig = sig[:, None] if sig.ndim == 1 else sig
    censored = prep.get("censored")
    if censored is None:
        censored = prep["censored"] = bool((np.abs(uh) == 1.0).any())
    if p.fixed and not censored:
        if "_d2" not in prep:  # Σ_j (u_j − μ_j)² and Σ_j (u_j − μ_j), cached: μ is fixed
            d = uh[:, None, :] - p.mu
            prep["_d2"], prep["_d1"] = np.einsum("nca,nca->nc", d, d), d.sum(axis=2)
        sq = prep["_d2"] - 2.0 * p.bias * prep["_d1"] + a * p.bias**2
        per = sq * (-0.5 / sig**2)
        per -= a * np.log(sig) + 0.5 * a * math.log(2 * math.pi)
    else:
        mean = p.mu + p.bias
        s3 = sig[:, :, None]
        z = (uh[:, None, :] - mean) / s3
        dens = -0.5 * z * z - np.log(s3) - 0.5 * math.log(2 * math.pi)
        if censored:
            hi, lo = (uh == 1.0)[:, None, :], (uh == -1.0)[:, None, :]
            dens = np.where(hi, special.log_ndtr((mean - 1.0) / s3), dens)
            dens = np.where(lo, special.log_ndtr((-1.0 - mean) / s3), dens)
        per = dens.sum(axis=2)
    per += p.logw
    top_ = per.max(axis=1, keepdims=True)
    top_[~np.isfinite(top_)] = 0.0
    per -= top_
    np.exp(per, out=per)
    with np.errstate(divide="ignore"):
        cont = np.log(per.sum(axis=1)) + top_[:, 0] - prep["log_volume"]
    if p.log_q is None:
        return cont
    zero = np.all(uh == 0.0, axis=1)
    log_q = np.minimum(p.log_q, 0.0)
    speak = np.log(-np.expm1(np.minimum(log_q, -1e-300)))
    return np.where(zero, log_q, speak + cont)


def prepare(fam: Family, data: Corrections) -> dict[str, np.ndarray]:
    """``fam.prepare`` plus the Jacobian of the a_max units (log-likelihoods in u_H's own
    units, so models compare)."""
    prep = fam.prepare(data)
    prep.pop("g", None)  # (n, Q, d): prepared, no longer needed
    prep.pop("lw_full", None)
    prep["log_volume"] = float(np.sum(np.log(data.task.action_bound)))
    return prep


def _take(prep: dict[str, Any], rows: np.ndarray) -> dict[str, Any]:
    """The prepared pieces of corrections ``rows`` (per-correction arrays sliced)."""
    out = {}
    n = len(prep["uh"])
    for key, value in prep.items():
        if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == n and n > 1:
            out[key] = value[rows]
        else:
            out[key] = value
    return out


_BLAS_SETTERS: list[tuple[Any, Any]] | None = None


def _blas_setters() -> list[tuple[Any, Any]]:
    """(get, set) thread-count functions of every OpenBLAS this process has loaded (Linux:
    found in /proc/self/maps; elsewhere none)."""
    global _BLAS_SETTERS
    if _BLAS_SETTERS is None:
        import ctypes

        found: list[tuple[Any, Any]] = []
        try:
            with open("/proc/self/maps") as maps:
                paths = {ln.split()[-1] for ln in maps if "openblas" in ln and "/" in ln}
        except OSError:
            paths = set()
        for path in sorted(paths):
            try:
                lib = ctypes.CDLL(path)
            except OSError:
                continue
            for pre in ("scipy_openblas", "openblas"):
                for suf in ("64_", ""):
                    get = getattr(lib, f"{pre}_get_num_threads{suf}", None)
                    put = getattr(lib, f"{pre}_set_num_threads{suf}", None)
                    if get is not None and put is not None:
                        found.append((get, put))
                        break
                else:
                    continue
                break
        _BLAS_SETTERS = found
    return _BLAS_SETTERS


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """OpenBLAS on one thread while L-BFGS-B runs, restored after: its threads wake for a
    problem of 2–4 parameters and, on a shared machine, wait for cores (measured: a 5-dataset
    recovery 27.7 s → 4.4 s at load 5 on 2 cores). The results do not change."""
    setters = _blas_setters()
    before = [get() for get, _ in setters]
    for _, put in setters:
        put(1)
    try:
        yield
    finally:
        for (_, put), n in zip(setters, before, strict=True):
            put(n)


def maximise(
    fam: Family, prep: dict[str, Any], starts: Sequence[dict[str, float]] | None = None
) -> tuple[dict[str, float], float]:
    """The maximum-likelihood values and the maximum log-likelihood."""
    with one_blas_thread():
        return _maximise(fam, prep, starts)


def _maximise(
    fam: Family, prep: dict[str, Any], starts: Sequence[dict[str, float]] | None
) -> tuple[dict[str, float], float]:
    params = fam.params

    def values(t: np.ndarray) -> dict[str, float]:
        return {p.name: p.from_free(x) for p, x in zip(params, t, strict=True)}

    def neg(t: np.ndarray) -> float:
        ll = loglik_terms(fam, prep, values(t)).sum()
        return float(-ll) if np.isfinite(ll) else 1e300

    if starts:  # a resample or a fold starts where the whole data's maximum is
        init = list(starts)
    else:  # a spread of σ: a mixture's surface can have more than one hill
        init = [{p.name: p.start for p in params}]
        init += [{**init[0], "sigma": s} for s in (0.1, 1.0)]
    best_t, best = None, math.inf
    for start in init:
        t0 = np.array([p.to_free(start[p.name]) for p in params])
        res = optimize.minimize(neg, t0, method="L-BFGS-B", bounds=[(-25, 25)] * len(params))
        if res.fun < best:
            best_t, best = res.x, float(res.fun)
    assert best_t is not None
    return values(best_t), -best


@dataclasses.dataclass
class Fit:
    """A fitted model: estimates, 95 % intervals, log-likelihood, held-out log-likelihood."""

    model: str
    n_people: int
    n_corrections: int
    estimate: dict[str, float]
    ci95: dict[str, tuple[float, float]]
    loglik: float
    heldout_loglik: float | None
    note: str = ""
    interval: str = "sandwich"

    def to_json(self) -> dict[str, Any]:
        return {
            "model": self.model,
            "n_people": self.n_people,
            "n_corrections": self.n_corrections,
            "params": {
                k: {"estimate": self.estimate[k], "ci95": [_finite(x) for x in self.ci95[k]]}
                for k in self.estimate
            },
            "interval": self.interval,
            "loglik": self.loglik,
            "heldout_loglik": self.heldout_loglik,
            "note": self.note,
        }


def _finite(x: float) -> float | None:
    """A number for JSON: None where there is none (NaN is not JSON)."""
    return float(x) if math.isfinite(x) else None


def usable(fam: Family, data: Corrections) -> tuple[Corrections, str]:
    """The corrections ``fam`` can be fitted to and a note on what was left out."""
    if not fam.needs_theta_hat:
        return data, ""
    ok = data.has_theta_hat
    if not ok.any():
        raise ValueError(
            f"--human {fam.name!r} teaches relative to θ̂, which these logs do not hold"
        )
    note = ""
    if data.theta_hat_source != "logged":
        note = f"fitted on θ̂ {data.theta_hat_source}"
    if not ok.all():
        note = (note + "; " if note else "") + f"{int((~ok).sum())} corrections without θ̂ left out"
    return data.subset(np.flatnonzero(ok)), note


INTERVALS = ("sandwich", "bca", "percentile")
"""How ``fit`` makes its 95 % intervals (all with the person as the unit; docs/humans.md,
"Intervals"): ``sandwich`` (the default) a Wald interval on the fitting scale from the
person-clustered leave-one-out covariance (:func:`leave_one_out_covariance`) with Student's t
on at most G − 1 degrees of freedom, ``bca`` the bias-corrected and accelerated bootstrap over
people with its tail probabilities widened for few people, ``percentile`` the plain percentile
bootstrap (kept to show why it was replaced: it under-covers with 12 people)."""
DEFAULT_INTERVAL = "sandwich"
"""``fit``'s interval (the recovery's coverage: docs/humans.md)."""
AT_BOUND = 7.0
"""A free-scale value beyond ±this is a parameter at its range's bound (logistic scale: within
0.09 % of the range's end). There the likelihood is flat, its Hessian and scores both vanish
and a Wald interval collapses onto the estimate (competence's p_good at 1 − 6e-8 gave
[1 − 4e-7, 1 − 1e-8]), so the bound gets a profile-likelihood interval instead."""


def free_values(fam: Family, v: dict[str, float]) -> np.ndarray:
    """Parameter values ``v`` on the optimiser's free scale (logistic or log)."""
    return np.array([p.to_free(v[p.name]) for p in fam.params])


def _values(fam: Family, t: np.ndarray) -> dict[str, float]:
    return {p.name: p.from_free(x) for p, x in zip(fam.params, t, strict=True)}


def _at_bound(fam: Family, t: np.ndarray) -> np.ndarray:
    out = np.abs(t) > AT_BOUND
    for j, p in enumerate(fam.params):
        if p.log:  # a log scale's range is clamped in from_free
            out[j] = not (p.low * (1 + 1e-6) < math.exp(t[j]) < p.high * (1 - 1e-6))
    return out


def person_scores(
    fam: Family, prep: dict[str, Any], data: Corrections, t: np.ndarray, h: float = 1e-4
) -> np.ndarray:
    """Each person's score (G, p): ∂ Σ_{i ∈ person} log p_i / ∂t on the free scale, by
    central differences of the per-correction log-likelihood."""
    groups = person_rows(data)
    out = np.zeros((len(groups), len(t)))
    for j in range(len(t)):
        up, down = t.copy(), t.copy()
        up[j] += h
        down[j] -= h
        d = loglik_terms(fam, prep, _values(fam, up)) - loglik_terms(fam, prep, _values(fam, down))
        d /= 2 * h
        out[:, j] = [d[g].sum() for g in groups]
    return out


def person_hessians(
    fam: Family, prep: dict[str, Any], data: Corrections, t: np.ndarray, h: float = 1e-3
) -> np.ndarray:
    """Each person's log-likelihood Hessian (G, p, p) on the free scale, by central
    differences of the per-correction log-likelihood; their sum is the whole data's."""
    return _group_hessians(fam, prep, t, person_rows(data), h)


def _group_hessians(
    fam: Family, prep: dict[str, Any], t: np.ndarray, groups: list[np.ndarray], h: float
) -> np.ndarray:
    n = len(t)

    def terms(x: np.ndarray) -> np.ndarray:
        return loglik_terms(fam, prep, _values(fam, x))

    per = np.zeros((len(terms(t)), n, n))
    f0 = terms(t)
    for i in range(n):
        for j in range(i, n):
            ei, ej = np.zeros(n), np.zeros(n)
            ei[i], ej[j] = h, h
            if i == j:
                d = (terms(t + ei) - 2 * f0 + terms(t - ei)) / h**2
            else:
                d = terms(t + ei + ej) - terms(t + ei - ej) - terms(t - ei + ej)
                d = (d + terms(t - ei - ej)) / (4 * h * h)
            per[:, i, j] = per[:, j, i] = d
    return np.stack([per[g].sum(axis=0) for g in groups])


def hessian(fam: Family, prep: dict[str, Any], t: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """The log-likelihood's Hessian (p, p) on the free scale, by central differences."""
    return _group_hessians(fam, prep, t, [np.arange(len(prep["uh"]))], h)[0]


def effective_people(
    inv: np.ndarray, per_person: np.ndarray, contrasts: np.ndarray | None = None
) -> np.ndarray:
    """Per parameter (or per column c of ``contrasts``, a linear combination of them), the
    Satterthwaite degrees of freedom of the clustered variance, (G−1)/G · (Σ_g λ_g)² / Σ_g λ_g²,
    with λ_g = cᵀ H⁻¹ H_g H⁻¹ c each person's share of the model's variance (Imbens & Kolesár
    2016's idea for few clusters): G − 1 when the people inform alike, fewer when a few carry the
    information (e.g. most of the others' corrections sit on the action bound)."""
    g = len(per_person)
    c = np.eye(len(inv)) if contrasts is None else contrasts
    lam = np.einsum("kj,kl,glm,mn,nj->gj", c, inv, per_person, inv, c)
    lam = np.maximum(lam, 0.0)
    den = (lam**2).sum(axis=0)
    df = np.divide(lam.sum(axis=0) ** 2, den, out=np.full(lam.shape[1], float(g)), where=den > 0)
    return np.maximum(df * (g - 1) / g, 1.0)


def leave_one_out_covariance(per_person: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """The person-clustered covariance of the estimate from each person's one-step
    leave-one-out shift, (G−1)/G Σ_g d_g d_gᵀ with d_g = (H − H_g)⁻¹ s_g (the jackknife over
    people without refitting: "CR3", MacKinnon, Nielsen & Webb 2023), ``per_person`` the
    people's information matrices −H_g (G, p, p) and ``scores`` their scores s_g (G, p). With
    few people the plain sandwich H⁻¹ Σ s_g s_gᵀ H⁻¹ · G/(G−1) ("CR1") is too small: a person's
    own corrections pull the estimate toward them, so their score at it understates their
    misfit; the one-step shift undoes that pull. Measured on the recovery datasets: margin-noise's
    ε 75 → 85 %, its indifference threshold 90 → 100 % (docs/humans.md)."""
    g = len(per_person)
    info = per_person.sum(axis=0)
    shifts = np.stack([np.linalg.solve(info - per_person[k], scores[k]) for k in range(g)])
    return shifts.T @ shifts * (g - 1) / g


def _derived_gradient(fam: Family, t: np.ndarray, h: float = 1e-6) -> dict[str, np.ndarray]:
    """∂(derived parameter)/∂t on the free scale, by central differences (``Family.derive``)."""
    names = list(fam.derive(_values(fam, t)))
    out = {k: np.zeros(len(t)) for k in names}
    for j in range(len(t)):
        up, down = t.copy(), t.copy()
        up[j] += h
        down[j] -= h
        hi, lo = fam.derive(_values(fam, up)), fam.derive(_values(fam, down))
        for k in names:
            out[k][j] = (hi[k] - lo[k]) / (2 * h)
    return out


class _Fixed(Family):
    """``base`` with parameter ``name`` held at ``value`` (the profile likelihood's inner fit)."""

    def __init__(self, base: Family, name: str, value: float) -> None:
        self.base, self.fixed_name, self.value = base, name, value
        self.name = base.name
        self.params = tuple(p for p in base.params if p.name != name)

    def prepare(self, data):
        return self.base.prepare(data)

    def parts(self, prep, v):
        return self.base.parts(prep, {**v, self.fixed_name: self.value})

    def terms(self, prep, v):
        return self.base.terms(prep, {**v, self.fixed_name: self.value})


def _one_sided(fam: Family, prep: dict[str, Any], t: np.ndarray, j: int, level: float) -> float:
    """For a parameter at its bound: the free value where the profile log-likelihood (the
    others refitted) has fallen by χ²₁(2·level − 1)/2 from its maximum (a one-sided
    likelihood-ratio bound; the others held at their estimate fell far too fast where they
    trade off with it, e.g. competence's p_good against p_bad)."""
    from scipy.stats import chi2

    drop = 0.5 * float(chi2.ppf(2 * level - 1, 1))
    inward = -np.sign(t[j]) if t[j] != 0 else 1.0
    base = float(loglik_terms(fam, prep, _values(fam, t)).sum())
    param = fam.params[j]
    mle = _values(fam, t)
    others = {k: v for k, v in mle.items() if k != param.name}

    def gap(x: float) -> float:
        inner = _Fixed(fam, param.name, param.from_free(x))
        if not inner.params:
            ll = float(loglik_terms(inner, prep, {}).sum())
        else:
            _, ll = maximise(inner, prep, starts=[others])
        return (base - ll if np.isfinite(ll) else math.inf) - drop

    far = t[j] + inward * 50.0
    if gap(far) < 0:
        return far
    return float(optimize.brentq(gap, t[j], far, xtol=1e-3))


def sandwich_intervals(
    fam: Family,
    prep: dict[str, Any],
    data: Corrections,
    mle: dict[str, float],
    level: float = 0.95,
) -> dict[str, tuple[float, float]]:
    """Wald intervals on the free scale from the person-clustered covariance
    (:func:`leave_one_out_covariance`), Student's t on the :func:`effective_people` degrees of
    freedom (at most G − 1), mapped back (so they stay in each parameter's range). A parameter at
    its bound gets a one-sided likelihood-ratio interval from the bound (``_one_sided``). A
    derived parameter (``Family.derive``) gets the delta method's Wald interval on its own
    scale, the parameters at a bound held."""
    from scipy.stats import t as student

    t = free_values(fam, mle)
    g = len(data.people)
    bound = _at_bound(fam, t)
    free = np.flatnonzero(~bound)
    out: dict[str, tuple[float, float]] = {}
    derived = fam.derive(mle)
    if len(free) and g >= 2:
        per = -person_hessians(fam, prep, data, t)[:, free][:, :, free]
        s = person_scores(fam, prep, data, t)[:, free]
        try:
            inv = np.linalg.inv(per.sum(axis=0))
            cov = leave_one_out_covariance(per, s)
            df = effective_people(inv, per)
        except np.linalg.LinAlgError:
            inv = cov = np.full((len(free), len(free)), math.inf)
            df = np.full(len(free), 1.0)
        for k, j in enumerate(free):
            se = math.sqrt(cov[k, k]) if np.isfinite(cov[k, k]) and cov[k, k] >= 0 else math.inf
            q = float(student.ppf(0.5 + level / 2, df[k]))
            p = fam.params[j]
            lo = p.from_free(max(t[j] - q * se, -50.0))
            hi = p.from_free(min(t[j] + q * se, 50.0))
            out[p.name] = (lo, hi)
        for name, grad in _derived_gradient(fam, t).items():
            c = grad[free]
            var = float(c @ cov @ c)
            dfc = effective_people(inv, per, c[:, None])[0] if np.isfinite(inv).all() else 1.0
            se = math.sqrt(var) if math.isfinite(var) and var >= 0 else math.inf
            q = float(student.ppf(0.5 + level / 2, dfc))
            out[name] = (derived[name] - q * se, derived[name] + q * se)
    for j in np.flatnonzero(bound):
        p = fam.params[j]
        edge = p.from_free(math.copysign(50.0, t[j]))  # the bound itself
        ends = sorted((edge, p.from_free(_one_sided(fam, prep, t, int(j), level))))
        out[p.name] = (ends[0], ends[1])
    for name in [p.name for p in fam.params] + list(derived):
        out.setdefault(name, (math.nan, math.nan))
    return out


def bootstrap_draws(
    fam: Family,
    prep: dict[str, Any],
    data: Corrections,
    mle: dict[str, float],
    n_boot: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """(n_boot, p) maximum-likelihood values on the free scale, refitted to resamples of the
    people with replacement (each person's corrections together)."""
    groups = person_rows(data)
    draws = np.empty((n_boot, len(fam.params)))
    for b in range(n_boot):
        pick = rng.integers(0, len(groups), len(groups))
        rows = np.concatenate([groups[i] for i in pick])
        v, _ = maximise(fam, _take(prep, rows), starts=[mle])
        draws[b] = free_values(fam, v)
    return draws


def jackknife_draws(
    fam: Family, prep: dict[str, Any], data: Corrections, mle: dict[str, float]
) -> np.ndarray:
    """(G, p) free-scale estimates with each person left out in turn (BCa's acceleration)."""
    groups = person_rows(data)
    out = np.empty((len(groups), len(fam.params)))
    for i in range(len(groups)):
        rows = np.concatenate([g for j, g in enumerate(groups) if j != i])
        v, _ = maximise(fam, _take(prep, rows), starts=[mle])
        out[i] = free_values(fam, v)
    return out


def expanded_level(level: float, n_people: int) -> float:
    """The two-sided level whose normal quantile is √(G/(G−1)) t_{G−1}: the bootstrap over G
    people sees a spread (G−1)/G of the truth's and normal tails where Student's belong, so
    its intervals are too narrow for few people (Hesterberg 2015, "expanded percentile")."""
    from scipy.stats import norm
    from scipy.stats import t as student

    if n_people < 2:
        return level
    q = math.sqrt(n_people / (n_people - 1)) * float(student.ppf(0.5 + level / 2, n_people - 1))
    return float(2 * norm.cdf(q) - 1)


def bca_intervals(
    fam: Family,
    draws: np.ndarray,
    jack: np.ndarray | None,
    mle: dict[str, float],
    n_people: int,
    level: float = 0.95,
) -> dict[str, tuple[float, float]]:
    """BCa intervals (Efron 1987) from bootstrap ``draws`` on the free scale: the percentiles
    moved by the bias correction z₀ (the share of draws below the estimate) and the acceleration
    a (the jackknife's skewness), at the ``expanded_level`` for ``n_people``; ``jack`` None
    gives the plain percentile interval at ``level``. A derived parameter (``Family.derive``)
    takes the same percentiles of its value at each draw."""
    t = free_values(fam, mle)
    cols: list[tuple[str, np.ndarray, float, np.ndarray | None, Callable[[float], float]]] = [
        (p.name, draws[:, j], float(t[j]), None if jack is None else jack[:, j], p.from_free)
        for j, p in enumerate(fam.params)
    ]
    derived = fam.derive(mle)
    if derived:
        d_draws = [fam.derive(_values(fam, row)) for row in draws]
        d_jack = None if jack is None else [fam.derive(_values(fam, row)) for row in jack]
        for name, value in derived.items():
            dj = None if d_jack is None else np.array([r[name] for r in d_jack])
            cols.append((name, np.array([r[name] for r in d_draws]), value, dj, float))
    return {name: _bca(d, est, jk, n_people, level, back) for name, d, est, jk, back in cols}


def _bca(
    d: np.ndarray, est: float, jack: np.ndarray | None, n_people: int, level: float, back: Any
) -> tuple[float, float]:
    """One column's BCa (or, ``jack`` None, percentile) interval, mapped by ``back``."""
    from scipy.stats import norm

    if jack is None:
        lo_p, hi_p = 0.5 - level / 2, 0.5 + level / 2
    else:
        wide = expanded_level(level, n_people)
        share = (np.sum(d < est) + 0.5 * np.sum(d == est)) / len(d)
        z0 = float(norm.ppf(min(max(share, 0.5 / len(d)), 1 - 0.5 / len(d))))
        dev = jack.mean() - jack
        den = 6.0 * float(np.sum(dev**2)) ** 1.5
        acc = float(np.sum(dev**3)) / den if den > 0 else 0.0
        ends = []
        for z in (norm.ppf(0.5 - wide / 2), norm.ppf(0.5 + wide / 2)):
            ends.append(float(norm.cdf(z0 + (z0 + z) / (1 - acc * (z0 + z)))))
        lo_p, hi_p = ends
    lo, hi = np.quantile(d, [lo_p, hi_p])
    return (back(float(lo)), back(float(hi)))


def bootstrap(
    fam: Family,
    prep: dict[str, Any],
    data: Corrections,
    mle: dict[str, float],
    n_boot: int,
    rng: np.random.Generator,
    method: str = "bca",
) -> dict[str, tuple[float, float]]:
    """95 % intervals over people: ``method`` "bca" (default) or "percentile" from ``n_boot``
    resamples of the people, "sandwich" without resampling (:data:`INTERVALS`)."""
    if method not in INTERVALS:
        raise ValueError(f"interval method must be one of {', '.join(INTERVALS)}, got {method!r}")
    if method == "sandwich":
        return sandwich_intervals(fam, prep, data, mle)
    draws = bootstrap_draws(fam, prep, data, mle, n_boot, rng)
    jack = jackknife_draws(fam, prep, data, mle) if method == "bca" else None
    return bca_intervals(fam, draws, jack, mle, len(data.people))


FEW_PEOPLE = (
    "intervals over people and the held-out log-likelihood (folds of people) need at least 2 "
    "people (participants, or episodes where the log names none)"
)
"""What a fit of one person says instead of a degenerate interval and a NaN held-out score."""


def heldout(
    fam: Family,
    prep: dict[str, Any],
    data: Corrections,
    folds: int,
    rng: np.random.Generator,
    start: dict[str, float] | None = None,
) -> float:
    """Σ over folds of people of the held-out people's log-likelihood under the others' fit;
    ValueError with fewer than 2 people or folds (:data:`FEW_PEOPLE`)."""
    groups = person_rows(data)
    n = len(groups)
    folds = min(folds, n)
    if folds < 2:
        raise ValueError(f"held-out log-likelihood: {FEW_PEOPLE}; these logs hold {n}")
    order = rng.permutation(n)
    total = 0.0
    for f in range(folds):
        test = np.concatenate([groups[i] for i in order[f::folds]])
        train = np.concatenate([groups[i] for j, i in enumerate(order) if j % folds != f])
        v, _ = maximise(fam, _take(prep, train), starts=[start] if start else None)
        total += float(loglik_terms(fam, _take(prep, test), v).sum())
    return total


def fit(
    name: str,
    data: Corrections,
    *,
    n_boot: int = 200,
    folds: int = 5,
    seed: int = 0,
    heldout_too: bool = True,
    interval: str = DEFAULT_INTERVAL,
) -> Fit:
    """Fit registered human ``name`` to ``data``: MLE, 95 % intervals over people
    (``interval``, :data:`INTERVALS`; the bootstrap ones from ``n_boot`` resamples, none when
    it is 0) and (``heldout_too``) the held-out log-likelihood over ``folds`` folds of people.
    With one person there are no intervals and no held-out score, and the note says why."""
    fam = family(name)
    if interval not in INTERVALS:
        raise ValueError(f"interval must be one of {', '.join(INTERVALS)}, got {interval!r}")
    data, note = usable(fam, data)
    prep = prepare(fam, data)
    mle, ll = maximise(fam, prep)
    few = len(data.people) < 2
    ci: dict[str, tuple[float, float]] = {}
    if not few and (n_boot or interval == "sandwich"):
        ci = bootstrap(fam, prep, data, mle, n_boot, np.random.default_rng(seed), interval)
    held = None
    if heldout_too and not few:
        held = heldout(fam, prep, data, folds, np.random.default_rng(seed + 1), mle)
    if few:
        note = (note + "; " if note else "") + f"one person: {FEW_PEOPLE}"
    estimate = {**mle, **fam.derive(mle)}
    ci = {k: ci.get(k, (math.nan, math.nan)) for k in estimate}
    return Fit(name, len(data.people), len(data), estimate, ci, ll, held, note, interval)


PARSIMONY_LEVEL = 0.05
"""The likelihood-ratio test's level in the parsimony rule (:func:`select`)."""
PARSIMONY_RULE = (
    "the highest held-out log-likelihood, except that a model which reduces to a simpler "
    "compared one at fixed parameter values (mistaken, reversing at rate 0; skipping at p 0; "
    "feature-noise at κ 0; over, under at scale 1; competence at p_good = p_bad = 1: each "
    "nominal) gives way to it unless a likelihood-ratio test on all the corrections rejects "
    "the simpler at 5 % (restrictions on a range's bound: the χ̄² mixture of Self & Liang 1987)"
)
"""The rule ``--compare`` selects a model by (docs/humans.md, "Model selection")."""


def chi_bar_pvalue(lr: float, restrictions: int, on_bound: int) -> float:
    """P(LR ≥ ``lr``) under the simpler model when ``restrictions`` parameters are fixed, of
    which ``on_bound`` at their range's bound: Σ_j C(b, j) 2^−b P(χ²_{k−b+j} ≥ lr) (Self & Liang
    1987, for restrictions whose estimates are asymptotically independent; χ²₀ is the point
    mass at 0). Not 0.5·χ²₁ alone: one bound restriction is 1 − (½ + ½ P(χ²₁ < lr))."""
    from scipy.stats import chi2

    if lr <= 0:
        return 1.0
    b, k = on_bound, restrictions
    total = 0.0
    for j in range(b + 1):
        dof = k - b + j
        tail = 0.0 if dof == 0 else float(chi2.sf(lr, dof))
        total += math.comb(b, j) / 2**b * tail
    return total


@dataclasses.dataclass(frozen=True)
class Selection:
    """What the parsimony rule (:data:`PARSIMONY_RULE`) chose and why."""

    chosen: str
    by_heldout: str
    steps: tuple[str, ...]

    def to_json(self) -> dict[str, Any]:
        return {
            "rule": PARSIMONY_RULE,
            "chosen": self.chosen,
            "highest_heldout": self.by_heldout,
            "why": list(self.steps),
        }


def select(fits: dict[str, Fit], level: float = PARSIMONY_LEVEL) -> Selection:
    """The model the parsimony rule picks among ``fits`` (each with a held-out score): the
    highest held-out log-likelihood, then down each nesting (``Family.reduces_to``) to a
    compared simpler model fitted to the same corrections while the likelihood-ratio test
    (:func:`chi_bar_pvalue`) does not reject the simpler at ``level``."""
    scored = {k: f for k, f in fits.items() if f.heldout_loglik is not None}
    if not scored:
        raise ValueError(f"model selection: {FEW_PEOPLE}")
    best = max(scored, key=lambda k: scored[k].heldout_loglik)  # type: ignore[arg-type,return-value]
    steps = [f"{best}: highest held-out log-likelihood ({scored[best].heldout_loglik:.2f})"]
    chosen = best
    while True:
        fam = family(chosen)
        if fam.reduces_to is None:
            break
        simpler, at = fam.reduces_to
        big, small = fits[chosen], fits.get(simpler)
        if small is None or small.n_corrections != big.n_corrections:
            break
        ranges = {p.name: p for p in fam.params}
        on_bound = sum(1 for k, v in at.items() if v in (ranges[k].low, ranges[k].high))
        lr = max(0.0, 2.0 * (big.loglik - small.loglik))
        pval = chi_bar_pvalue(lr, len(at), on_bound)
        fixed = ", ".join(f"{k} = {v:g}" for k, v in at.items())
        if pval < level:
            steps.append(
                f"{chosen} kept over {simpler} ({chosen} at {fixed}): likelihood ratio "
                f"{lr:.2f}, p = {pval:.3g} < {level:g}"
            )
            break
        steps.append(
            f"{simpler} chosen over {chosen} ({chosen} at {fixed}): likelihood ratio {lr:.2f}, "
            f"p = {pval:.3g} ≥ {level:g}"
        )
        chosen = simpler
    return Selection(chosen, best, tuple(steps))


# ---------------------------------------------------------------------------- predictive draws
def simulate(
    name: str, data: Corrections, values: dict[str, float], rng: np.random.Generator
) -> np.ndarray:
    """u_H (n, a) drawn from the fitted model at the logged corrections' states (x, u_R, θ*,
    θ̂): the posterior-predictive draw ``--compare`` plots against the real corrections. Where
    the log clips at the bound, the draw is clipped too."""
    fam = family(name)
    data, _ = usable(fam, data)
    prep = prepare(fam, data)
    own = fam.sample(prep, values, rng)
    if own is not None:
        return own * np.asarray(data.task.action_bound)
    p = fam.parts(prep, values)
    n, c, a = len(prep["uh"]), p.mu.shape[1], p.mu.shape[2]
    w = np.exp(p.logw - special.logsumexp(p.logw, axis=1, keepdims=True))
    idx = np.minimum((w.cumsum(axis=1) < rng.random((n, 1))).sum(axis=1), c - 1)
    mu = np.broadcast_to(p.mu, (n, c, a))[np.arange(n), idx]
    sig = p.sigma if p.sigma.ndim == 1 else p.sigma[np.arange(n), idx]
    u = mu + p.bias + sig[:, None] * rng.standard_normal((n, a))
    if (np.abs(prep["uh"]) == 1.0).any():
        u = np.clip(u, -1.0, 1.0)
    if p.log_q is not None:
        u[rng.random(n) < np.exp(p.log_q)] = 0.0
    return u * np.asarray(data.task.action_bound)


__all__ = [
    "FEW_PEOPLE",
    "INTERVALS",
    "NOT_FITTABLE",
    "PARSIMONY_RULE",
    "Corrections",
    "Family",
    "Fit",
    "Param",
    "Selection",
    "bca_intervals",
    "best_for_theta",
    "bootstrap",
    "bootstrap_draws",
    "chi_bar_pvalue",
    "expanded_level",
    "families",
    "family",
    "fit",
    "free_values",
    "heldout",
    "jackknife_draws",
    "leave_one_out_covariance",
    "loglik_terms",
    "maximise",
    "order_weights",
    "person_rows",
    "prepare",
    "quadrature",
    "sandwich_intervals",
    "select",
    "simulate",
    "teacher_choice",
]
