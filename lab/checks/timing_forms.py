"""Which timing hazard the real people's correction times choose (``strol_gym.humans.timing``).

Candidates beyond the shipped ``reactive`` form (s capped at 1): the shortfall uncapped, capped
at a fitted k, saturating as 1 − e^{−s/k} with a fitted k, log(min(s, 1) + ε) with a fitted ε,
measured against what the person would accept (max(min(s, 1) − s0, 0), fitted s0); a rate per
person (a gamma frailty, variance v, shared by a person's sessions); and three covariates added
to the shipped form: the shortfall the last correction removed, the corrections made so far and
the session's clock (minutes of the robot's motion). A fitted scale is profiled on a grid inside
every fit (so it is refitted in every fold and bootstrap sample).

Selected by the leave-one-person-out log-likelihood on the One and MOF sessions only; then
checked on the StROL sessions held out: their log-likelihood, and the StROL/One count ratio the
fit expects along the logged paths with its person-bootstrap interval. The frailty's held-out
likelihood conditions each person's rate on their own One and MOF sessions (the same people
held out on another learner).

    python -m lab.checks.timing_forms LOGS --reps 200

LOGS: ``strol-bench import-study DATA --out LOGS --theta0 implied --authors-ghat GDIR``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy.optimize import minimize
from scipy.special import gammaln

from strol_gym.benchmarks.sessions import fit_timing
from strol_gym.humans import timing

DT = fit_timing.DT
FIT = ("one", "mof")
Transform = Callable[[np.ndarray], np.ndarray]


def _cap(k: float) -> Transform:
    return lambda s: np.minimum(s, k)


def _sat(k: float) -> Transform:
    return lambda s: -np.expm1(-s / k)


def _caplog(e: float) -> Transform:
    return lambda s: np.log(np.minimum(s, 1.0) + e)


def _accept(a: float) -> Transform:
    return lambda s: np.maximum(np.minimum(s, 1.0) - a, 0.0)


KS = (0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0)
FORMS: dict[str, list[Transform]] = {
    "capped at 1 (shipped)": [_cap(1.0)],
    "uncapped": [lambda s: s],
    "capped at fitted k": [_cap(k) for k in KS],
    "1 - exp(-s/k), fitted k": [_sat(k) for k in KS],
    "log(min(s,1) + eps), fitted eps": [_caplog(e) for e in (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)],
    "against acceptance s0, fitted": [_accept(a) for a in (0.0, 0.05, 0.1, 0.2, 0.3)],
}
EXTRAS = (
    "last push's effect",
    "corrections so far",
    "clock (min)",
    "before the first correction",
    *(f"plan accepted (s < {s0:g})" for s0 in (0.05, 0.1, 0.2)),
    "Task 1's own shortfall slope",
    "wait x shortfall",
)
IMPATIENT_EXTRAS = (
    "nothing more",
    "Task 1's own shortfall slope",
    "Task 1's own impatience",
    "Task 1's own wait slope",
    "plan accepted (s < 0.1)",
    "plan accepted (s < 0.1) x wait",
    "corrections so far",
    "clock (min)",
    "robot arrived",
    "shortfall x path left",
    "path left",
)
"""Rows on the shipped ``impatient`` form (a_Task + b s + (c + d s) log(1 + τ)) with one
covariate more: min(s, 1) or min(s, 1)·log(1 + τ) or log(1 + τ) in Task 1 only (Task 1's own
reaction: its low-shortfall rate is read off Tasks 2-3 otherwise), 1 (or log(1 + τ)) while the
plan is within 0.1 of θ*'s, log(1 + corrections so far), minutes of the robot's motion; 1 once
the robot stands at its goal, min(s, 1) times the share of its current plan still to play, or
that share alone (the authors' robot played each plan over 45 s less the motion so far, at
least 5 s, then held its last waypoint: it arrives at max(45, t_last + 5) s of motion)."""
ARRIVE, LEAST = 45.0, 5.0
"""One covariate more: the shortfall the last correction removed, log(1 + corrections so far),
the minutes of the robot's motion, 1 until the first correction (the first push's timing its
own), 1 while the robot's plan is within s0 of θ*'s (a person satisfied with what the robot
does: a drop in the rate at a good plan, beyond the shortfall's slope), min(s, 1) in Task 1
only (Task 1's shorter sessions in the authors' code: its own reaction to the plan),
log(1 + τ)·min(s, 1) (impatience only while the plan is poor)."""


@dataclasses.dataclass
class Result:
    coef: list[float]
    fit: float
    heldout: float
    ratio: float
    frailty_v: float = math.nan
    task1_strol: float = math.nan
    """Corrections expected along Task 1's StROL paths (one covariate more only)."""


def _map(sessions: Sequence[timing.TimedSession], fn: Transform) -> list[timing.TimedSession]:
    return [dataclasses.replace(s, shortfall=fn(s.shortfall)) for s in sessions]


def _split(sessions: Sequence[timing.TimedSession]) -> tuple[list, list, list]:
    train = [s for s in sessions if s.learner in FIT]
    test = [s for s in sessions if s.learner == "strol"]
    one = [s for s in sessions if s.learner == "one"]
    return train, test, one


def _best(train: Sequence[timing.TimedSession], fns: list[Transform]) -> tuple[Any, Transform]:
    fits = [(timing.fit(_map(train, fn), "reactive", DT), fn) for fn in fns]
    return max(fits, key=lambda v: v[0].loglik)


# ---------------------------------------------------------------- a rate per person (frailty)
def _session_parts(ss: Sequence[timing.TimedSession], coef: np.ndarray) -> np.ndarray:
    """Per session (Σ_events η, compensator Λ, events)."""
    d, k = timing.design(ss, DT), len(coef)  # the reactive form's first five columns
    ev = np.bincount(d.event_session, d.at_events[:, :k] @ coef, minlength=d.n_sessions)
    lam = DT * np.bincount(d.grid_session, np.exp(d.grid[:, :k] @ coef), minlength=d.n_sessions)
    return np.stack([ev, lam, [len(s.events) for s in ss]], axis=1)


def _by_person(ss: Sequence[timing.TimedSession], parts: np.ndarray) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for s, p in zip(ss, parts, strict=True):
        out[s.person] = out.get(s.person, np.zeros(3)) + p
    return out


def _marginal(e: float, lam: float, n: float, a: float, b: float) -> float:
    """log L of a person's events with rate Z·e^η, Z ~ Gamma(shape a, rate b), Z integrated."""
    return float(e + gammaln(a + n) - gammaln(a) + a * math.log(b) - (a + n) * math.log(b + lam))


def _fit_frailty(train: Sequence[timing.TimedSession]) -> tuple[np.ndarray, float, float]:
    start = timing.fit(train, "reactive", DT).coef[:5]
    d = timing.design(train, DT)
    d = dataclasses.replace(d, grid=d.grid[:, :5], at_events=d.at_events[:, :5])
    people = sorted({s.person for s in train})
    idx = np.array([people.index(s.person) for s in train])
    n = np.bincount(idx, [len(s.events) for s in train], len(people))

    def nll(x: np.ndarray) -> float:
        v = math.exp(x[5])
        ev = np.bincount(d.event_session, d.at_events @ x[:5], minlength=d.n_sessions)
        lam = DT * np.bincount(d.grid_session, np.exp(d.grid @ x[:5]), minlength=d.n_sessions)
        e, lp = np.bincount(idx, ev, len(people)), np.bincount(idx, lam, len(people))
        return -sum(_marginal(e[i], lp[i], n[i], 1 / v, 1 / v) for i in range(len(people)))

    bounds = [(-30.0, 10.0)] * 3 + [(-10.0, 10.0), (-5.0, 5.0), (-8.0, 3.0)]
    r = minimize(nll, np.r_[start, math.log(0.1)], method="L-BFGS-B", bounds=bounds)
    return r.x[:5], math.exp(r.x[5]), -float(r.fun)


def _frailty(sessions: Sequence[timing.TimedSession], fns: list[Transform]) -> Result:
    train, test, one = _split(sessions)
    fn = _best(train, fns)[1]
    train, test, one = _map(train, fn), _map(test, fn), _map(one, fn)
    coef, v, ll = _fit_frailty(train)
    post = {
        p: (1 / v + q[2], 1 / v + q[1])
        for p, q in _by_person(train, _session_parts(train, coef)).items()
    }
    held = sum(
        _marginal(q[0], q[1], q[2], *post[p])
        for p, q in _by_person(test, _session_parts(test, coef)).items()
    )

    def expected(ss: list[timing.TimedSession]) -> float:
        lam = _session_parts(ss, coef)[:, 1]
        return float(
            sum(post[s.person][0] / post[s.person][1] * m for s, m in zip(ss, lam, strict=True))
        )

    return Result(coef.tolist(), ll, held, expected(test) / expected(one), v)


def _frailty_lopo(sessions: Sequence[timing.TimedSession], fns: list[Transform]) -> float:
    train = _split(sessions)[0]
    total = 0.0
    for p in sorted({s.person for s in train}):
        rest = [s for s in train if s.person != p]
        fn = _best(rest, fns)[1]
        coef, v, _ = _fit_frailty(_map(rest, fn))
        q = _session_parts(_map([s for s in train if s.person == p], fn), coef).sum(axis=0)
        total += _marginal(q[0], q[1], q[2], 1 / v, 1 / v)
    return total


# ---------------------------------------------------------------- one covariate more
def _extra_columns(
    s: timing.TimedSession, extra: str, seg: np.ndarray, wait: np.ndarray, now: np.ndarray
) -> np.ndarray:
    """Columns a_1..a_3, min(s, 1), log(1 + τ), ``extra`` at rows in plan segment ``seg``."""
    sf = np.minimum(s.shortfall, 1.0)
    o = np.zeros((len(seg), 6))
    o[:, s.task - 1] = 1.0
    o[:, 3] = sf[seg]
    o[:, 4] = np.log1p(wait * DT)
    if extra == EXTRAS[0]:
        o[:, 5] = np.r_[0.0, np.maximum(sf[:-1] - sf[1:], 0.0)][seg]
    elif extra == EXTRAS[1]:
        o[:, 5] = np.log1p(seg)
    elif extra == EXTRAS[2]:
        o[:, 5] = now * DT / 60.0
    elif extra == EXTRAS[3]:
        o[:, 5] = seg == 0
    elif extra == EXTRAS[7]:
        o[:, 5] = sf[seg] * (s.task == 1)
    elif extra == EXTRAS[8]:
        o[:, 5] = sf[seg] * np.log1p(wait * DT)
    else:
        s0 = float(extra.split("< ")[1].rstrip(")"))
        o[:, 5] = s.shortfall[seg] < s0
    return o


def _impatient_columns(
    s: timing.TimedSession, extra: str, seg: np.ndarray, wait: np.ndarray, now: np.ndarray
) -> np.ndarray:
    """Columns a_1..a_3, min(s, 1), log(1 + τ), min(s, 1)·log(1 + τ), ``extra``
    (:data:`IMPATIENT_EXTRAS`) at rows in plan segment ``seg``."""
    sf = np.minimum(s.shortfall, 1.0)[seg]
    lw = np.log1p(wait * DT)
    o = np.zeros((len(seg), 7))
    o[:, s.task - 1] = 1.0
    o[:, 3], o[:, 4], o[:, 5] = sf, lw, sf * lw
    t1 = float(s.task == 1)
    last = (now - wait) * DT
    arrive = np.where(seg > 0, np.maximum(ARRIVE, last + LEAST), ARRIVE) / DT
    left = np.clip((arrive - now) / np.maximum(arrive - (now - wait) * (seg > 0), 1.0), 0.0, 1.0)
    col = {
        IMPATIENT_EXTRAS[0]: np.zeros(len(seg)),
        IMPATIENT_EXTRAS[1]: sf * t1,
        IMPATIENT_EXTRAS[2]: sf * lw * t1,
        IMPATIENT_EXTRAS[3]: lw * t1,
        IMPATIENT_EXTRAS[4]: (s.shortfall[seg] < 0.1) * 1.0,
        IMPATIENT_EXTRAS[5]: (s.shortfall[seg] < 0.1) * lw,
        IMPATIENT_EXTRAS[6]: np.log1p(seg),
        IMPATIENT_EXTRAS[7]: now * DT / 60.0,
        IMPATIENT_EXTRAS[8]: (now >= arrive) * 1.0,
        IMPATIENT_EXTRAS[9]: sf * left,
        IMPATIENT_EXTRAS[10]: left,
    }
    o[:, 6] = col[extra]
    return o


def _columns(
    s: timing.TimedSession, extra: str, seg: np.ndarray, wait: np.ndarray, now: np.ndarray
) -> np.ndarray:
    if extra.startswith(IMPATIENT):
        return _impatient_columns(s, extra[len(IMPATIENT) :], seg, wait, now)
    return _extra_columns(s, extra, seg, wait, now)


IMPATIENT = "impatient + "
"""Prefix of an ``extra`` on the impatient form (:func:`_columns`)."""


def _extra_design(ss: Sequence[timing.TimedSession], extra: str) -> tuple[np.ndarray, ...]:
    """(grid rows, their sessions, event rows, their sessions) of :func:`_extra_columns`."""
    grid, gs, at, es = [], [], [], []
    for i, s in enumerate(ss):
        t = np.arange(s.samples)
        k = np.searchsorted(s.events, t, side="left")
        j = np.arange(len(s.events))
        grid.append(_columns(s, extra, k, t - np.r_[0, s.events][k], t))
        gs.append(np.full(len(t), i))
        at.append(_columns(s, extra, j, s.events - np.r_[0, s.events][j], s.events))
        es.append(np.full(len(j), i))
    return np.concatenate(grid), np.concatenate(gs), np.concatenate(at), np.concatenate(es)


def fit_columns(x: np.ndarray, xe: np.ndarray) -> np.ndarray:
    """The maximum-likelihood coefficients of a hazard exp(x · c) on the path grid ``x`` with
    events at rows ``xe`` (first three columns: the Tasks' intercepts); Newton's method, a
    column all zero (no such term, a Task absent) left at 0 (an intercept at −30)."""
    keep = np.abs(x).sum(0) > 0
    c = np.zeros(x.shape[1])
    c[:3] = np.where(keep[:3], -3.0, -30.0)
    x, xe = x[:, keep], xe[:, keep]
    ck = c[keep]
    for _ in range(timing.NEWTON_ITERS):
        w = DT * np.exp(x @ ck)
        hess = (x * w[:, None]).T @ x + 1e-9 * np.eye(len(ck))
        step = np.linalg.solve(hess, xe.sum(0) - x.T @ w)
        big = float(np.abs(step).max())
        ck = ck + (step * 2.0 / big if big > 2.0 else step)
        if big < 1e-10:
            break
    c[keep] = ck
    return c


def _extra_fit(ss: Sequence[timing.TimedSession], extra: str) -> np.ndarray:
    x, _, xe, _ = _extra_design(ss, extra)
    return fit_columns(x, xe)


def _extra_ll(ss: Sequence[timing.TimedSession], extra: str, c: np.ndarray) -> float:
    x, _, xe, _ = _extra_design(ss, extra)
    return float((xe @ c).sum() - DT * np.exp(x @ c).sum())


def _extra(sessions: Sequence[timing.TimedSession], extra: str) -> Result:
    train, test, one = _split(sessions)
    c = _extra_fit(train, extra)

    def expected(ss: list[timing.TimedSession]) -> float:
        return float(DT * np.exp(_extra_design(ss, extra)[0] @ c).sum())

    held = _extra_ll(test, extra, c)
    ratio = expected(test) / expected(one)
    t1 = expected([s for s in test if s.task == 1])
    return Result(c.tolist(), _extra_ll(train, extra, c), held, ratio, task1_strol=t1)


def _extra_lopo(sessions: Sequence[timing.TimedSession], extra: str) -> float:
    train = _split(sessions)[0]
    total = 0.0
    for p in sorted({s.person for s in train}):
        c = _extra_fit([s for s in train if s.person != p], extra)
        total += _extra_ll([s for s in train if s.person == p], extra, c)
    return total


# ---------------------------------------------------------------- the shortfall's forms
def _form(sessions: Sequence[timing.TimedSession], fns: list[Transform]) -> Result:
    train, test, one = _split(sessions)
    f, fn = _best(train, fns)
    pred = timing.predicted_counts(f, _map(test + one, fn))
    ratio = float(pred[: len(test)].sum() / pred[len(test) :].sum())
    return Result(f.coef.tolist(), f.loglik, timing.loglik(f, _map(test, fn)), ratio)


def _form_lopo(sessions: Sequence[timing.TimedSession], fns: list[Transform]) -> float:
    train = _split(sessions)[0]
    total = 0.0
    for p in sorted({s.person for s in train}):
        f, fn = _best([s for s in train if s.person != p], fns)
        total += timing.loglik(f, _map([s for s in train if s.person == p], fn))
    return total


def _bootstrap(sessions: Sequence[timing.TimedSession], run: Callable, reps: int) -> list[float]:
    """95 % interval of the predicted ratio over people resampled (a resampled person counts
    as a new person: the frailty's rate is per copy)."""
    people = sorted({s.person for s in sessions})
    by = {p: [s for s in sessions if s.person == p] for p in people}
    rng = np.random.default_rng(fit_timing.BOOT_SEED)
    out = []
    for _ in range(reps):
        pick = rng.integers(0, len(people), len(people))
        sample = [
            dataclasses.replace(s, person=f"{j}") for j, i in enumerate(pick) for s in by[people[i]]
        ]
        out.append(run(sample).ratio)
    return np.percentile(out, [2.5, 97.5]).tolist()


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs")
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--rows", default="", help="rows to run, e.g. 2,3,4 (default: every row)")
    args = ap.parse_args(argv)
    sessions, _ = fit_timing.read_timed(args.logs, cap=math.inf)
    _, test, one = _split(sessions)
    real = sum(len(s.events) for s in test) / sum(len(s.events) for s in one)
    print(f"real StROL/One {real:.3f}; {len(test)} StROL sessions held out")
    rows: list[tuple[str, Callable, Callable]] = []
    for name, fns in FORMS.items():
        rows.append((name, lambda ss, f=fns: _form(ss, f), lambda ss, f=fns: _form_lopo(ss, f)))
    cap = FORMS["capped at 1 (shipped)"]
    rows.append(
        (
            "capped at 1 + a rate per person",
            lambda ss: _frailty(ss, cap),
            lambda ss: _frailty_lopo(ss, cap),
        )
    )
    for extra in (*EXTRAS, *(IMPATIENT + e for e in IMPATIENT_EXTRAS)):
        rows.append(
            (
                f"capped at 1 + {extra}",
                lambda ss, e=extra: _extra(ss, e),
                lambda ss, e=extra: _extra_lopo(ss, e),
            )
        )
    print("form | LOPO log L (One, MOF) | held-out log L (StROL) | StROL/One [95 %] | coef (v; …)")
    pick = {int(v) for v in args.rows.split(",") if v}
    for k, (name, run, lopo) in enumerate(rows):
        if pick and k not in pick:
            continue
        r = run(sessions)
        lo, hi = _bootstrap(sessions, run, args.reps) if args.reps else (math.nan, math.nan)
        v = f" v={r.frailty_v:.3f}" if math.isfinite(r.frailty_v) else ""
        v += f"; Task 1 StROL expected {r.task1_strol:.1f}" if math.isfinite(r.task1_strol) else ""
        coef = ", ".join(f"{c:+.3f}" for c in r.coef)
        cells = f"{lopo(sessions):.1f} | {r.heldout:.1f} | {r.ratio:.3f} [{lo:.3f}, {hi:.3f}]"
        print(f"{name} | {cells} | {coef}{v}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
