"""When a person steps in: the hazard of a correction along a session, as a function of what
the robot does (the timing half of ``hazard``, fitted to when people corrected).

``hazard`` (``strol_gym.humans.findings``) decides per correction opportunity whether the
person steps in, from the margin of that correction. Along a session the person does not see
an opportunity but a robot playing its plan; the hazard here is the same proportional form,
per second of the robot's path:

    rate(t) = exp(a_Task + b · s(t) + (c + d · s(t)) · log(1 + τ(t)))   (corrections per second)

- s(t), the **shortfall** of the robot's current plan: its regret under θ* (planned from the
  Task's start with the robot's θ̂ at t, eq. S1) over the regret of a robot that knows
  nothing (the median over θ̂ uniform in [−1, 1]^d), capped at 1: 0 = the person's own
  plan, 1 = as bad as a random start or worse. b > 0 is a person who corrects a worse robot
  sooner (a reactive person); b = 0 a person whose corrections do not depend on the robot
  (the count a budget);
- τ(t), the seconds since the last correction (or the session's start): c < 0 a person who
  waits longer after each push, c > 0 one who corrects in bursts;
- d, **impatience**: how much more waiting weighs while the plan is poor (d > 0: a person
  whose urge to step in grows the longer a poor plan plays, and who settles while a good one
  does).

:func:`fit` maximises the likelihood of the logged correction times (a Poisson process on the
grid of path samples, ``dt`` s apart: log L = Σ_events η − dt Σ_t e^η) by Newton's method;
:func:`predicted_counts` is the count the fit expects along a logged path (the compensator),
the quantity a held-out learner's real count is compared with. Models are named by the terms
they keep (:data:`MODELS`): ``rate`` (a_Task: the Task's mean count, what the budget gives),
``wait`` (+ c), ``reactive`` (+ b), ``impatient`` (+ d).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence

import numpy as np

from strol_gym import checks
from strol_gym.tasks.study import StudyTask

TERMS = ("shortfall", "wait", "impatience")
MODELS: dict[str, tuple[str, ...]] = {
    "rate": (),
    "wait": ("wait",),
    "reactive": ("shortfall", "wait"),
    "impatient": ("shortfall", "wait", "impatience"),
}
"""The nested timing models by the terms they add to the Task's rate."""
TASKS = (1, 2, 3)
MAX_SAMPLES = 1_000_000
"""The most path samples one session may have."""
NEWTON_ITERS = 100


@dataclasses.dataclass(frozen=True)
class TimedSession:
    """One session as the timing likelihood sees it."""

    person: str
    task: int
    learner: str
    samples: int
    """Path samples (the session lasted ``samples · dt`` s of the robot's own motion)."""
    events: np.ndarray
    """Path sample of each correction (sorted, ints in [0, samples))."""
    shortfall: np.ndarray
    """s in effect before each correction and after the last (len(events) + 1)."""

    def __post_init__(self) -> None:
        n = int(checks.number("samples", self.samples, low=1, high=MAX_SAMPLES, integer=True))
        ev = np.asarray(self.events, dtype=np.int64).reshape(-1)
        if len(ev) and (ev.min() < 0 or ev.max() >= n or np.any(np.diff(ev) < 0)):
            raise ValueError(f"events must be sorted path samples in [0, {n}), got {ev.tolist()}")
        s = np.asarray(self.shortfall, dtype=np.float64).reshape(-1)
        if len(s) != len(ev) + 1 or not np.isfinite(s).all():
            raise ValueError(f"shortfall must hold {len(ev) + 1} finite numbers, got {len(s)}")
        if self.task not in TASKS:
            raise ValueError(f"task must be one of {TASKS}, got {self.task!r}")
        object.__setattr__(self, "samples", n)
        object.__setattr__(self, "events", ev)
        object.__setattr__(self, "shortfall", s)


@dataclasses.dataclass(frozen=True)
class Design:
    """The sessions' covariates on the sample grid (``grid``) and at the corrections
    (``at_events``), columns: the three Tasks' intercepts, then :data:`TERMS`."""

    grid: np.ndarray
    grid_session: np.ndarray
    at_events: np.ndarray
    event_session: np.ndarray
    n_sessions: int


def design(sessions: Sequence[TimedSession], dt: float) -> Design:
    """Covariates of every path sample and every correction (module docstring): a sample t
    sees the θ̂ after the corrections logged before it and τ since the latest of them."""
    grids, gs, evs, es = [], [], [], []
    for i, s in enumerate(sessions):
        t = np.arange(s.samples)
        k = np.searchsorted(s.events, t, side="left")  # corrections strictly before t
        last = np.concatenate([[0], s.events])[k]
        grids.append(_columns(s.task, s.shortfall[k], (t - last) * dt))
        gs.append(np.full(s.samples, i))
        j = np.arange(len(s.events))
        prev = np.concatenate([[0], s.events])[j]
        evs.append(_columns(s.task, s.shortfall[j], (s.events - prev) * dt))
        es.append(np.full(len(j), i))
    return Design(
        np.concatenate(grids), np.concatenate(gs), np.concatenate(evs), np.concatenate(es),
        len(sessions),
    )  # fmt: skip


def _columns(task: int, shortfall: np.ndarray, wait: np.ndarray) -> np.ndarray:
    out = np.zeros((len(shortfall), len(TASKS) + len(TERMS)))
    out[:, task - 1] = 1.0
    out[:, 3] = shortfall
    out[:, 4] = np.log1p(wait)
    out[:, 5] = shortfall * out[:, 4]
    return out


def _keep(model: str) -> np.ndarray:
    if model not in MODELS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
    return np.array([True] * len(TASKS) + [t in MODELS[model] for t in TERMS])


@dataclasses.dataclass(frozen=True)
class TimingFit:
    """A fitted timing model: coefficients (a_1, a_2, a_3, b, c, d; zero where the model has
    no such term), the log-likelihood of the sessions fitted and ``dt``."""

    model: str
    coef: np.ndarray
    loglik: float
    dt: float

    @property
    def params(self) -> dict[str, float]:
        names = ("rate_task1", "rate_task2", "rate_task3", *TERMS)
        return {n: float(v) for n, v in zip(names, self.coef, strict=True)}


def loglik_parts(d: Design, coef: np.ndarray, dt: float) -> np.ndarray:
    """Per session, log L = Σ_events η − dt Σ_t e^η (the Poisson process on the grid)."""
    ev = np.bincount(d.event_session, d.at_events @ coef, minlength=d.n_sessions)
    mass = np.bincount(d.grid_session, np.exp(d.grid @ coef), minlength=d.n_sessions)
    return ev - dt * mass


def fit(sessions: Sequence[TimedSession], model: str = "reactive", dt: float = 0.05) -> TimingFit:
    """The maximum-likelihood ``model`` (:data:`MODELS`) on ``sessions`` (Newton's method on
    the concave log-likelihood; a Task without sessions keeps a_Task = −30, no corrections)."""
    keep = _keep(model)
    dt = float(checks.number("dt", dt, low=0.0, low_open=True, high=60.0))
    d = design(sessions, dt)
    present = np.isin(np.arange(len(TASKS)), [s.task - 1 for s in sessions])
    keep = keep & np.concatenate([present, [True] * len(TERMS)])
    x, xe = d.grid[:, keep], d.at_events[:, keep]
    coef = np.zeros(keep.sum())
    total = float(len(d.at_events)) / max(dt * len(d.grid), 1e-12)
    coef[: present.sum()] = math.log(max(total, 1e-6))
    target = xe.sum(axis=0)
    for _ in range(NEWTON_ITERS):
        w = dt * np.exp(x @ coef)
        grad = target - x.T @ w
        hess = (x * w[:, None]).T @ x + 1e-9 * np.eye(len(coef))
        step = np.linalg.solve(hess, grad)
        coef = coef + _damped(step)
        if float(np.abs(step).max()) < 1e-10:
            break
    full = np.zeros(len(keep))
    full[: len(TASKS)] = -30.0
    full[keep] = coef
    return TimingFit(model, full, float(loglik_parts(d, full, dt).sum()), dt)


def _damped(step: np.ndarray, most: float = 2.0) -> np.ndarray:
    big = float(np.abs(step).max())
    return step * (most / big) if big > most else step


def loglik(f: TimingFit, sessions: Sequence[TimedSession]) -> float:
    """log L of ``sessions`` under the fit (held-out sessions: a held-out likelihood)."""
    return float(loglik_parts(design(sessions, f.dt), f.coef, f.dt).sum())


def predicted_counts(f: TimingFit, sessions: Sequence[TimedSession]) -> np.ndarray:
    """Per session, the corrections the fit expects along its logged path: dt Σ_t e^η (the
    compensator; a model that fits has Σ predicted ≈ Σ real on any set of sessions)."""
    d = design(sessions, f.dt)
    return f.dt * np.bincount(d.grid_session, np.exp(d.grid @ f.coef), minlength=d.n_sessions)


def rate(f: TimingFit | np.ndarray, task: int, shortfall: float, wait: float) -> float:
    """Corrections per second at shortfall s and τ s since the last correction (``f``: a fit,
    or its coefficients (a_1, a_2, a_3, b, c[, d]))."""
    coef = f.coef if isinstance(f, TimingFit) else np.asarray(f, dtype=np.float64)
    return hazard_rate((coef[task - 1], *coef[3:]), shortfall, wait)


def hazard_vector(name: str, value: object) -> tuple[float, ...]:
    """One Task's hazard (a, b, c[, d]) checked: 3 or 4 numbers in [−50, 50] (ValueError
    naming ``name``)."""
    v = checks.vector(name, value)
    if len(v) not in (3, 4):
        raise ValueError(f"{name} must hold 3 or 4 numbers (a, b, c[, d]), got {len(v)}")
    for label, x in zip("abcd", v.tolist(), strict=False):
        checks.number(f"{name} ({label})", x, low=-50.0, high=50.0)
    return tuple(float(x) for x in v)


def hazard_rate(hazard: Sequence[float], shortfall: float, wait: float) -> float:
    """Corrections per second of one Task's hazard (a, b, c[, d]: d 0 where not given) at
    shortfall s and τ s since the last correction (module docstring)."""
    a, b, c, d = (*(float(v) for v in hazard), 0.0)[:4]
    eta = a + b * shortfall + (c + d * shortfall) * math.log1p(max(wait, 0.0))
    return math.exp(min(eta, 50.0))


def simulate(
    hazard: Sequence[float],
    samples: int,
    switches: np.ndarray,
    shortfall: np.ndarray,
    dt: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """The path samples at which a person with ``hazard`` (a, b, c[, d]) corrects along a logged
    path of ``samples`` samples whose plan's shortfall is ``shortfall[k]`` from the k-th of the
    sorted path samples ``switches`` on (``shortfall[0]`` before the first): the robot's plan
    as logged, τ since the person's own last correction. One uniform per sample, drawn in a
    block: P(correct at t) = 1 − exp(−rate·dt), the likelihood's discrete process."""
    n = int(checks.number("samples", samples, low=0, high=MAX_SAMPLES, integer=True))
    a, b, c, d = (*(float(v) for v in hazard), 0.0)[:4]
    t = np.arange(n)
    s = np.asarray(shortfall, dtype=np.float64)[np.searchsorted(switches, t, side="right")]
    u = rng.random(n)
    events: list[int] = []
    start = last = 0
    while start < n:  # the next event: the first sample from ``start`` whose draw hits
        k, sk = t[start:], s[start:]
        eta = np.minimum(a + b * sk + (c + d * sk) * np.log1p((k - last) * dt), 50.0)
        hit = np.flatnonzero(u[start:] < -np.expm1(-np.exp(eta) * dt))
        if not len(hit):
            break
        last = start + int(hit[0])
        events.append(last)
        start = last + 1
    return np.array(events, dtype=np.int64)


DOUBLED_TASKS = (1,)
"""The study Tasks whose session ends on the authors' doubled count: their Task 1 loop added
the robot's motion since the last correction to its elapsed time a second time at each
correction, so a session ended when the motion plus the motion before its last correction
reached the budget (:func:`doubled_end`); Tasks 2-3 counted the motion once."""


def doubled_end(events: np.ndarray, budget: int) -> tuple[np.ndarray, int]:
    """(the corrections made, the path samples the session lasted) of a session whose elapsed
    time is the motion t plus the motion before its last correction (:data:`DOUBLED_TASKS`),
    ended when that reaches ``budget`` samples, for a person who would correct at the sorted
    path samples ``events`` (a stopping time: corrections past the end are not made). It ends
    at a correction at t_k when 2·t_k ≥ budget, else at budget − t_last."""
    budget = int(checks.number("budget", budget, low=1, high=MAX_SAMPLES, integer=True))
    last = 0
    for k, e in enumerate(np.asarray(events, dtype=np.int64).tolist()):
        if e + last >= budget:  # the session ended before this one
            return np.asarray(events[:k], dtype=np.int64), budget - last
        last = e
        if 2 * e >= budget:
            return np.asarray(events[: k + 1], dtype=np.int64), e + 1
    return np.asarray(events, dtype=np.int64), budget - last


UNIT_DRAWS = 64
UNIT_SEED = 0


@functools.cache
def _unit(task: StudyTask, theta_star: tuple[float, ...]) -> float:
    rng = np.random.default_rng(UNIT_SEED)
    th = rng.uniform(-1.0, 1.0, (UNIT_DRAWS, task.dim))
    star = np.broadcast_to(np.asarray(theta_star), th.shape)
    start = np.repeat(np.asarray(task.start, dtype=np.float64)[None], UNIT_DRAWS, 0)
    return float(np.median(task.regret(th, star, start)))


def shortfall_unit(task: StudyTask, theta_star: np.ndarray) -> float:
    """The median regret (from the Task's start) of θ̂ uniform in [−1, 1]^d, drawn with seed
    ``UNIT_SEED``: the shortfall's unit, a robot that knows nothing (cached per Task and θ*)."""
    return _unit(task, tuple(float(v) for v in np.asarray(theta_star, dtype=np.float64)))


SHORTFALL_CAP = 1.0
"""s saturates here: a plan as bad as a random start's or worse looks equally bad. Chosen by
the leave-one-person-out log-likelihood on the One and MOF sessions among s, min(s, 1),
log(s + 0.05), √s and max(s − 0.3, 0) (docs/study.md)."""


def shortfall(
    task: StudyTask, theta_star: np.ndarray, theta_hats: np.ndarray, cap: float = SHORTFALL_CAP
) -> np.ndarray:
    """s (n,) for each θ̂ (n, d): the regret of θ̂'s plan from the Task's start (eq. S1) over
    :func:`shortfall_unit`, at most ``cap`` (:data:`SHORTFALL_CAP`; ``math.inf``: uncapped,
    to compare the shortfall's forms)."""
    hats = np.atleast_2d(np.asarray(theta_hats, dtype=np.float64))
    star = np.broadcast_to(np.asarray(theta_star, dtype=np.float64), hats.shape)
    start = np.repeat(np.asarray(task.start, dtype=np.float64)[None], len(hats), 0)
    s = task.regret(hats, star, start) / shortfall_unit(task, theta_star)
    return np.minimum(s, cap)


def step_in_probability(rate_per_s: float, dt: float) -> float:
    """P(a correction within dt s) at a constant rate: 1 − exp(−rate·dt), the hazard's own
    form (``HazardModel``'s h = 1 − exp(−λ e^{γ(m−1)}))."""
    return -math.expm1(-rate_per_s * dt)


__all__ = [
    "DOUBLED_TASKS",
    "MODELS",
    "SHORTFALL_CAP",
    "TERMS",
    "Design",
    "TimedSession",
    "TimingFit",
    "design",
    "doubled_end",
    "fit",
    "hazard_rate",
    "hazard_vector",
    "loglik",
    "loglik_parts",
    "predicted_counts",
    "rate",
    "shortfall",
    "shortfall_unit",
    "simulate",
    "step_in_probability",
]
