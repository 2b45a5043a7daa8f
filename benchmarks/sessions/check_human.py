"""``strol-bench check-human LOGS (--human NAME | --population | --person MODULE:ATTR) --out
OUT``: does a simulated person make the corrections the real people made?

LOGS is a folder of real session logs as ``strol-bench import-study`` writes them (the study's
108 sessions). For each of ``--draws`` replicates the person simulates every real session, and
per study Task each :data:`STATISTICS` entry is computed on the replicate as on the real logs:

- ``count_one`` / ``count_mof`` / ``count_strol``: corrections per session under each learner
  (correction lines: a correction with at least two logged poses);
- ``when_median``: the median share of the robot's path at which the corrections start;
- ``size_median``, ``size_small``: the median ‖u_H / a_max‖ and the share below 0.7 a_max;
- ``angle_median``, ``angle_over_90``: the angle (°) between u_H and θ*'s steepest ascent
  (a_max ⊙ ∇ₓ(θ*·φ), both in units of a_max: ``strol_gym.humans.aim.steepest_ascent``), its
  median and the share above 90°;
- ``raised``: the share of corrections with θ*·g(x, u_H, u_R) > 0.

**The band is joint.** A check passes when the real value lies in its band; the bands' level
is set so that a person that is right fails *any* check in at most 5 % of runs (:func:`judge`,
the min-p rule made exact): the real value is ranked as one more replicate, each of the S + 1
values gets its two-sided rank p-value per check among all S + 1 (itself counted) and its
smallest over the checks, and γ, the per-check level, is the (⌊0.05·(S + 1)⌋ + 1)-th smallest of
those (Bonferroni's 0.05 / J made exact for the checks' dependence). The real value fails a
check when its p there is below γ, which at most ⌊0.05·(S + 1)⌋ of the S + 1 exchangeable values
do, whichever of them is the real one. ``--draws`` must be at least :func:`min_draws` (2·J/0.05
− 1 for J checks), so that a real value beyond every replicate can fail.

**Who simulates.** A :class:`Person` turns the real sessions of one Task into simulated ones:

- ``--human NAME`` (any registered human, ``--human-kwargs`` JSON, ``--sigma``, ``--bias``,
  ``--beta``): :class:`AtLoggedMoments`, the model's correction at each logged moment (x, u_R,
  θ*, θ̂ where the log holds it). It says *how* a person pushes, not *when* nor how often, so the
  count and timing checks are reported as not simulated; a u_H = 0 (a silent person) drops the
  correction;
- ``--population``: :class:`StudyPopulation`, StROL-Study-v2's fitted participants
  (``strol_gym.envs.study.population``): the shipped people correct when their timing hazard
  says, given the plan the robot logged along each real session (count and timing simulated),
  each correction the population's at the session's logged state nearest along the path; a
  population without a timing fit has a budget per (user, Task) and its timing is not simulated;
- ``--person MODULE:ATTR``: any object (or a callable returning one) with ``decides_count``,
  ``decides_when`` and ``sessions(real, rng)``, see :class:`Person`.

Writes OUT/report.json (every check: real value, replicates' median, band, p, pass or fail or
null where not simulated; the band's γ; the first ``--keep`` replicates' statistics), OUT/report.md
(the table), OUT/check.png (the figure) and OUT/sessions/draw_NNN/ (the first ``--keep``
replicates as session logs in import-study's format, so that anyone can recompute them:
:func:`read_sessions` and :func:`statistics` read them as they read the real ones).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from strol_gym.envs.study.metrics import AUTHORS_DT
from strol_gym.humans.aim import steepest_ascent
from strol_gym.tasks.base import Task

if TYPE_CHECKING:
    from strol_gym.tasks.study import StudyTask

LEARNERS = ("one", "mof", "strol")
"""The study's learners, as import-study names them."""
SMALL = 0.7
"""A small correction: ‖u_H / a_max‖ below this."""
STATISTICS = (
    *(f"count_{name}" for name in LEARNERS),
    "when_median",
    "size_median",
    "size_small",
    "angle_median",
    "angle_over_90",
    "raised",
)
"""The statistics checked per study Task (module docstring)."""
COUNTS = tuple(s for s in STATISTICS if s.startswith("count_"))
WHEN = ("when_median",)
LEVEL = 0.95
"""The joint band's level: a right person fails no check in at least this share of runs."""
DRAWS = 2000
"""The replicates by default: twice :func:`min_draws` for the population's 27 checks."""
MAX_DRAWS = 100_000
MAX_KEEP = 1_000
MAX_LOGS = 10_000
MAX_LOG_BYTES = 50_000_000
MAX_CORRECTIONS = 10_000
"""The most corrections one real or simulated session may hold."""


# ---------------------------------------------------------------------------- the sessions
@dataclasses.dataclass
class Session:
    """One session as this check reads it: its Task (and study number), learner, user, θ*,
    path length and corrections (dicts with x, u_h, u_r, path_sample and, where logged,
    theta_hat_before), and the log's own header and episode lines (to write replicates)."""

    task: Task
    number: int
    learner: str
    user: str
    theta_star: np.ndarray
    path_samples: int
    corrections: list[dict[str, Any]]
    header: dict[str, Any]
    episode: dict[str, Any]
    name: str


def read_sessions(folder: str | Path) -> list[Session]:
    """Every session log under ``folder`` (import-study's format: the header names the learner
    and ``extra`` the user and study Task); ValueError naming the file on anything else."""
    from strol_gym.benchmarks.sessions.replay_folder import find_logs
    from strol_gym.files import loads_json
    from strol_gym.wrappers.session_log import read_session, session_task

    paths = find_logs(folder)
    if len(paths) > MAX_LOGS:
        raise ValueError(f"LOGS: more than {MAX_LOGS} session logs")
    out = []
    tasks: dict[str, Task] = {}  # one Task per logged Task: its cached values are shared
    for path in paths:
        if path.stat().st_size > MAX_LOG_BYTES:
            raise ValueError(f"LOGS {path}: larger than {MAX_LOG_BYTES // 1_000_000} MB")
        session = read_session(path)  # checks the file's structure
        key = json.dumps([session.header["task"], session.header["task_describe"]], sort_keys=True)
        if key not in tasks:
            tasks[key] = session_task(session)
        recs = [loads_json(line, str(path)) for line in path.read_bytes().splitlines() if line]
        header = recs[0]
        extra = header.get("extra") if isinstance(header.get("extra"), dict) else {}
        number, user = extra.get("study_task"), extra.get("user")
        if not isinstance(number, int) or number not in (1, 2, 3) or user is None:
            raise ValueError(
                f"LOGS {path}: not an imported study session (its header's extra needs "
                "study_task 1-3 and user: strol-bench import-study writes them)"
            )
        episodes = [r for r in recs if r.get("type") == "episode"]
        corr = [r for r in recs if r.get("type") == "correction"]
        if len(episodes) != 1 or len(corr) > MAX_CORRECTIONS:
            raise ValueError(
                f"LOGS {path}: one episode and at most {MAX_CORRECTIONS} corrections expected"
            )
        ep = episodes[0]
        rows = [
            {
                "x": np.asarray(c["x"], dtype=np.float64),
                "u_h": np.asarray(c["u_h"], dtype=np.float64),
                "u_r": np.asarray(c["u_r"], dtype=np.float64),
                "path_sample": c.get("path_sample"),
                "theta_hat_before": c.get("theta_hat_before"),
                "theta_hat_after": c.get("theta_hat_after"),
            }
            for c in corr
        ]
        out.append(
            Session(
                task=tasks[key],
                number=number,
                learner=str(header.get("learner")),
                user=str(user),
                theta_star=np.asarray(ep["theta_star"], dtype=np.float64),
                path_samples=int(ep.get("path_samples") or 0),
                corrections=rows,
                header=header,
                episode=ep,
                name=path.name,
            )
        )
    return out


def by_task(sessions: Sequence[Session]) -> dict[int, list[Session]]:
    """The sessions of each study Task (1-3), in their order."""
    out: dict[int, list[Session]] = {}
    for s in sessions:
        out.setdefault(s.number, []).append(s)
    return dict(sorted(out.items()))


# ---------------------------------------------------------------------------- statistics
def statistics(
    sessions: Sequence[Session], corrections: Sequence[Sequence[dict[str, Any]]] | None = None
) -> dict[str, float]:
    """The :data:`STATISTICS` of one Task's ``sessions`` (their own corrections, or
    ``corrections``: one list per session, in order). NaN where nothing is left to measure."""
    rows = [s.corrections for s in sessions] if corrections is None else corrections
    out: dict[str, float] = {}
    for name in LEARNERS:
        counts = [len(r) for s, r in zip(sessions, rows, strict=True) if s.learner == name]
        out[f"count_{name}"] = float(np.mean(counts)) if counts else math.nan
    flat = [(s, c) for s, r in zip(sessions, rows, strict=True) for c in r]
    when = [c["path_sample"] / _length(s, c) for s, c in flat if c.get("path_sample") is not None]
    out["when_median"] = float(np.median(when)) if when else math.nan
    if not flat:
        return {**out, **{k: math.nan for k in STATISTICS if k not in out}}
    task = sessions[0].task
    x = np.stack([c["x"] for _, c in flat])
    u = np.stack([c["u_h"] for _, c in flat])
    u_r = np.stack([c["u_r"] for _, c in flat])
    star = np.stack([s.theta_star for s, _ in flat])
    bound = np.asarray(task.action_bound, dtype=np.float64)
    size = np.linalg.norm(u / bound, axis=1)
    best = steepest_ascent(task, x, u_r, star)
    den = size * np.linalg.norm(best, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("na,na->n", u / bound, best) / den
    angle = np.degrees(np.arccos(np.clip(cos[den > 0], -1.0, 1.0)))
    gain = np.einsum("nd,nd->n", task.g(x, u, u_r), star)
    out["size_median"] = float(np.median(size))
    out["size_small"] = float(np.mean(size < SMALL))
    out["angle_median"] = float(np.median(angle)) if len(angle) else math.nan
    out["angle_over_90"] = float(np.mean(angle > 90.0)) if len(angle) else math.nan
    out["raised"] = float(np.mean(gain > 0.0))
    return out


def _length(s: Session, c: dict[str, Any]) -> int:
    """The path samples of the session correction ``c`` was made in: its own where a simulated
    session's length is the person's (``path_samples``), else the session's; at least 1."""
    n = c.get("path_samples")
    return max(int(s.path_samples if n is None else n), 1)


# ---------------------------------------------------------------------------- people
@runtime_checkable
class Person(Protocol):
    """A simulated person as check-human asks it: ``sessions(real, rng)`` returns, for the real
    sessions of one Task (in order), the simulated corrections of each (a list of dicts with
    ``x``, ``u_h``, ``u_r`` arrays and ``path_sample``, an index into the session's path or
    None). ``decides_count`` / ``decides_when``: whether how many corrections, and when, are
    the person's own (else those checks are reported as not simulated)."""

    decides_count: bool
    decides_when: bool
    name: str

    def sessions(
        self, real: Sequence[Session], rng: np.random.Generator
    ) -> list[list[dict[str, Any]]]: ...


class AtLoggedMoments:
    """A registered human model's correction at each logged moment of the real sessions (x,
    u_R, θ*, and θ̂ before it where the log holds it). The count and timing are the real ones:
    not simulated. A zero correction (a silent person) drops the moment."""

    decides_count = False
    decides_when = False

    def __init__(self, human: str, **params: Any) -> None:
        from strol_gym.humans import human_factory

        human_factory(human)  # an unknown name fails here, naming the registered ones
        self.human, self.params, self.name = human, params, human
        self._models: dict[int, Any] = {}

    def model(self, task: Task) -> Any:
        """The batched model for ``task``: a registered :class:`HumanModel` class built with its
        own defaults (a fitted model's fitted σ, ε) and the given parameters; any other
        registered human through ``human_model``."""
        from strol_gym.humans import HUMANS, HumanModel, human_model

        key = id(task)
        if key not in self._models:
            cls = HUMANS.get(self.human)
            if isinstance(cls, type) and issubclass(cls, HumanModel):
                self._models[key] = cls(task, **self.params)
            else:
                self._models[key] = human_model(self.human, task, **self.params)
        return self._models[key]

    def sessions(self, real, rng):
        task = real[0].task
        model = self.model(task)
        flat = [(i, c) for i, s in enumerate(real) for c in s.corrections]
        out: list[list[dict[str, Any]]] = [[] for _ in real]
        if not flat:
            return out
        x = np.stack([c["x"] for _, c in flat])
        u_r = np.stack([c["u_r"] for _, c in flat])
        star = np.stack([real[i].theta_star for i, _ in flat])
        hat = None
        if model.needs_theta_hat:
            known = [c["theta_hat_before"] for _, c in flat]
            if any(h is None for h in known):
                raise ValueError(
                    f"--human {self.human!r} teaches relative to θ̂, which these logs do not "
                    "hold before every correction (import-study --theta0 implied reconstructs "
                    "it for the One and MOF sessions only)"
                )
            hat = np.asarray(known, dtype=np.float64)
        u = model.correct(x, u_r, star, rng, hat)
        for (i, c), ui in zip(flat, u, strict=True):
            if np.any(ui != 0.0):
                out[i].append({**c, "u_h": ui, "theta_hat_before": None})
        return out


class StudyPopulation:
    """StROL-Study-v2's shipped population (``strol_gym.envs.study.population.shipped``): when
    and how often each person corrects is drawn from its timing hazard along the real session's
    path given the plan the robot logged (:func:`reacting_sessions`); its corrections are the
    population's (the intended push, unclipped) at the session's logged correction states in
    turn (the Task's other sessions' where it logged none)."""

    decides_count = True
    decides_when = True
    name = "population (StROL-Study-v2, fitted)"

    def __init__(self) -> None:
        self._plans: dict[int, tuple[Session, tuple[np.ndarray, np.ndarray]]] = {}
        self._aims: dict[int, tuple[Session, np.ndarray]] = {}

    def sessions(self, real, rng):
        from strol_gym.envs.study.population import aimed_aim, shipped

        pool = _pool(real)
        for r in real:  # each real session's plan and aims once (they plan), not per replicate
            if id(r) not in self._plans:
                self._plans[id(r)] = (r, logged_plan(r))
                states = _located(r) or pool
                x = [c["x"] for _, c in states]
                at = (
                    aimed_aim(_study_task(r.task), r.theta_star, np.stack(x))
                    if x
                    else np.empty((0, r.task.action_dim))
                )
                self._aims[id(r)] = (r, at)
        plans = {i: v[1] for i, v in self._plans.items()}
        aims = {i: v[1] for i, v in self._aims.items()}
        return reacting_sessions(shipped(), real, rng, plans, aims)


def logged_plan(s: Session) -> tuple[np.ndarray, np.ndarray]:
    """(path samples at which the robot's θ̂ changed, the plan's shortfall before the first and
    after each) of a real session, from its logged θ̂ (the episode's θ̂0 where none is
    logged)."""
    from strol_gym.humans.timing import shortfall

    task = _study_task(s.task)
    rows = [c for c in s.corrections if c.get("theta_hat_after") is not None]
    hats = [s.episode.get("theta_hat0")] + [c["theta_hat_after"] for c in rows]
    if hats[0] is None:
        hats[0] = np.asarray(task.prior_modes, dtype=np.float64).mean(axis=0)
    switches = np.array([int(c["path_sample"]) for c in rows], dtype=np.int64)
    return switches, shortfall(task, s.theta_star, np.asarray(hats, dtype=np.float64))


def _study_task(task: Task) -> StudyTask:
    """``task`` if it is a study Task, else ValueError (the population lives in them)."""
    from strol_gym.tasks.study import StudyTask

    if not isinstance(task, StudyTask):
        raise ValueError(f"--population simulates study sessions, not {task.task_id}")
    return task


def reacting_sessions(
    pop: Any,
    real: Sequence[Session],
    rng: np.random.Generator,
    plans: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
    aims: dict[int, np.ndarray] | None = None,
):
    """The shipped population's people (``Population.hazard``) along the real sessions: when
    each corrects is drawn from its timing hazard given the plan the robot logged
    (:func:`logged_plan`, ``timing.simulate``), each correction is the population's model of a
    correction at the session's logged correction state nearest along the path
    (:func:`nearest_states`; the Task's others' where it logged none), unclipped. ``plans``:
    :func:`logged_plan` of each session by ``id``, if already computed (it plans; a replicate
    need not plan again); ``aims``: likewise, ``population.aimed_aim`` at each of the session's
    states (its own logged ones, else the Task's), in order (the same bits as aiming at the
    picked states: the aim is computed row by row)."""
    from strol_gym.envs.study.population import aimed_aim, aimed_at
    from strol_gym.humans.timing import doubled_end, simulate

    task = _study_task(real[0].task)
    pool = _pool(real)
    out: list[list[dict[str, Any]]] = []
    for s in real:
        person = pop.draw(rng, s.number)
        switches, falls = plans[id(s)] if plans and id(s) in plans else logged_plan(s)
        budget = (getattr(pop, "doubled_budget", None) or {}).get(s.number)
        if budget is None:
            length = s.path_samples
            when = simulate(person.hazard, length, switches, falls, AUTHORS_DT, rng)
        else:  # the session ends on the authors' doubled count, by when this person corrects
            horizon = max(round(budget / AUTHORS_DT), 1)
            when = simulate(person.hazard, horizon, switches, falls, AUTHORS_DT, rng)
            when, length = doubled_end(when, horizon)
        when = when[:MAX_CORRECTIONS]
        states = _located(s) or pool
        if not len(when) or not states:
            out.append([])
            continue
        index = nearest_index(states, when / max(s.path_samples, 1))
        picked = [states[k][1] for k in index]
        if aims is not None and id(s) in aims:
            best = aims[id(s)][index]
        else:
            best = aimed_aim(task, s.theta_star, np.stack([c["x"] for c in picked]))
        n, a = len(picked), task.action_dim
        u = aimed_at(best, rng.standard_normal((n, a + 1)), rng.random(n), task)
        u = u * np.asarray(task.action_bound)
        out.append(
            [
                {
                    **c,
                    "u_h": ui,
                    "path_sample": int(k),
                    "path_samples": int(length),
                    "theta_hat_before": None,
                }
                for c, ui, k in zip(picked, u, when, strict=True)
            ]
        )
    return out


def _located(s: Session) -> list[tuple[float, dict[str, Any]]]:
    """(share of the path at which it started, correction) of each logged correction (NaN
    where it has no path sample)."""
    n = max(s.path_samples, 1)
    return [
        (math.nan if c.get("path_sample") is None else c["path_sample"] / n, c)
        for c in s.corrections
    ]


def _pool(real: Sequence[Session]) -> list[tuple[float, dict[str, Any]]]:
    """The Task's logged correction states (:func:`_located` of every session, in order): where
    a session logged none, its person is placed at these."""
    return [v for s in real for v in _located(s)]


def nearest_states(
    states: Sequence[tuple[float, dict[str, Any]]], share: np.ndarray
) -> list[dict[str, Any]]:
    """For each simulated correction at ``share`` of its path, the logged correction (``states``:
    (share of its own session's path, correction)) nearest along the path, the earlier on a
    tie: the robot's state where the person steps in, as near as the log holds it. Logged
    corrections without a path sample are taken in turn where none has one."""
    return [states[k][1] for k in nearest_index(states, share)]


def nearest_index(states: Sequence[tuple[float, Any]], share: np.ndarray) -> np.ndarray:
    """The indices into ``states`` that :func:`nearest_states` picks."""
    at = np.array([w for w, _ in states], dtype=np.float64)
    share = np.asarray(share, np.float64)
    if not np.isfinite(at).any():
        return np.arange(len(share), dtype=np.int64) % len(states)
    at = np.where(np.isfinite(at), at, np.inf)
    return np.array([int(np.argmin(np.abs(at - w))) for w in share], dtype=np.int64)


def person_from(spec: str) -> Person:
    """A :class:`Person` from ``--person MODULE:ATTR`` (an object, or a callable returning one);
    ValueError naming what is missing."""
    from strol_gym.registry import import_spec

    obj = import_spec(spec, "--person")
    if isinstance(obj, type) or (callable(obj) and not isinstance(obj, Person)):
        try:
            obj = obj()
        except TypeError as e:
            raise ValueError(f"--person {spec!r}: calling it with no arguments failed ({e})") from e
    if not isinstance(obj, Person):
        raise ValueError(
            f"--person {spec!r} must give an object with decides_count, decides_when, name and "
            "sessions(real, rng) (benchmarks/sessions/check_human.py: Person)"
        )
    return obj


# ---------------------------------------------------------------------------- the bands
def two_sided_p(draws: np.ndarray, value: float | np.ndarray) -> np.ndarray:
    """The two-sided rank p-value of ``value`` among ``draws`` (S,): 2·min(share ≤, share ≥),
    at most 1 (NaN for a NaN value)."""
    d = np.sort(draws[np.isfinite(draws)])
    v = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if not len(d):
        return np.full(v.shape, np.nan)
    le = np.searchsorted(d, v, side="right") / len(d)
    ge = (len(d) - np.searchsorted(d, v, side="left")) / len(d)
    p = np.minimum(1.0, 2.0 * np.minimum(le, ge))
    return np.where(np.isfinite(v), p, np.nan)


def joint_band(pool: np.ndarray, level: float = LEVEL) -> tuple[float, np.ndarray]:
    """γ and the bands (J, 2) of a ``pool`` (n, J) of exchangeable rows (the replicates and the
    real value, :func:`judge`): each row's smallest two-sided rank p-value over the J checks
    (:func:`two_sided_p` of the row among the pool, itself counted), and γ the
    (⌊(1 − level)·n⌋ + 1)-th smallest of those; check j's band is the range of its values whose
    p is at least γ. A row fails some check (p < γ) only if its smallest p is among the
    ⌊(1 − level)·n⌋ smallest: whichever row is the real one, at most that many of the n fail,
    so a real value exchangeable with the replicates fails any check with probability at most
    1 − level."""
    n, j = pool.shape
    p = np.column_stack([two_sided_p(pool[:, k], pool[:, k]) for k in range(j)])
    worst = np.sort(np.nanmin(np.where(np.isnan(p), np.inf, p), axis=1))
    gamma = float(worst[min(_tail(n, level), n - 1)])
    bands = np.full((j, 2), np.nan)
    for k in range(j):
        keep = pool[:, k][(p[:, k] >= gamma) & np.isfinite(pool[:, k])]
        if len(keep):
            bands[k] = keep.min(), keep.max()
    return gamma, bands


def _tail(n: int, level: float) -> int:
    """⌊(1 − level)·n⌋, the rows of a pool of n the band may fail (rounding's error aside)."""
    return math.floor((1.0 - level) * n + 1e-9)


def judge(
    replicates: np.ndarray, real: np.ndarray, level: float = LEVEL
) -> tuple[float, np.ndarray, np.ndarray]:
    """(γ, bands (J, 2), the real value's p per check) of ``real`` (J,) against ``replicates``
    (S, J): the real value is ranked as one more replicate and the band is set on all S + 1
    (:func:`joint_band`), so the real value and each replicate are judged alike. Check j passes
    when p[j] ≥ γ (the real value lies in its band); a NaN real value fails."""
    pool = np.vstack([replicates, np.asarray(real, dtype=np.float64)[None, :]])
    gamma, bands = joint_band(pool, level)
    p = np.array([two_sided_p(pool[:, k], pool[-1, k])[0] for k in range(pool.shape[1])])
    return gamma, bands, p


def min_draws(checks: int, level: float = LEVEL) -> int:
    """The fewest replicates S with which a real value beyond every replicate of a check can
    fail it: its p is then the smallest, 2/(S + 1), which at most 2 of the pool's values per
    check share, so the pool's tail ⌊(1 − level)·(S + 1)⌋ must hold 2·checks of them."""
    s = max(math.ceil(2 * checks / (1.0 - level)) - 3, 1)
    while _tail(s + 1, level) < 2 * checks:
        s += 1
    return s


def check_draws(draws: int, checks: int, level: float = LEVEL) -> None:
    """ValueError naming ``--draws`` and its minimum when ``draws`` replicates are too few for
    a joint band at ``level`` over ``checks`` checks (:func:`min_draws`)."""
    need = min_draws(checks, level)
    if draws < need:
        raise ValueError(
            f"--draws {draws} is too few for a joint {level:.0%} band over {checks} checks: at "
            f"least {need} (with fewer, a real value beyond every replicate could not fail)"
        )


# ---------------------------------------------------------------------------- the check
@dataclasses.dataclass
class Check:
    """One row of the report."""

    task: int
    statistic: str
    real: float
    median: float | None
    band: tuple[float, float] | None
    p: float | None
    passed: bool | None
    note: str = ""

    def to_json(self) -> dict[str, Any]:
        return {
            "task": self.task,
            "statistic": self.statistic,
            "real": _num(self.real),
            "simulated_median": _num(self.median),
            "band": None if self.band is None else [_num(v) for v in self.band],
            "p": _num(self.p),
            "pass": self.passed,
            "note": self.note,
        }


def _num(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def simulated(person: Person, statistic: str) -> str:
    """Why ``statistic`` is not simulated by ``person`` ("" when it is)."""
    if statistic in COUNTS and not person.decides_count:
        return "not simulated: the person corrects at the logged moments (how, not how often)"
    if statistic in WHEN and not person.decides_when:
        return "not simulated: the person does not decide when to correct"
    return ""


def run_check(
    real: Sequence[Session],
    person: Person,
    draws: int,
    seed: int,
    keep: int = 0,
    out: Path | None = None,
    values_out: dict[tuple[int, str], np.ndarray] | None = None,
    level: float = LEVEL,
) -> dict[str, Any]:
    """The report (module docstring) of ``person`` against the ``real`` sessions: ``draws``
    replicates from ``seed``; the first ``keep`` written under ``out/sessions``; each
    simulated check's replicate values into ``values_out`` (for the figure); the bands joint
    at ``level``."""
    tasks = by_task(real)
    real_stats = {t: statistics(ss) for t, ss in tasks.items()}
    cols = [(t, k) for t in tasks for k in STATISTICS if not simulated(person, k)]
    check_draws(draws, len(cols), level)
    values = np.full((draws, len(cols)), np.nan)
    kept: list[dict[str, dict[str, float]]] = []
    rng = np.random.default_rng(seed)
    for d in range(draws):
        row: dict[str, dict[str, float]] = {}
        for t, ss in tasks.items():
            sims = person.sessions(ss, rng)
            if len(sims) != len(ss):
                raise ValueError(f"{person.name}: {len(sims)} simulated sessions for {len(ss)}")
            row[str(t)] = statistics(ss, sims)
            if d < keep and out is not None:
                write_replicate(out / "sessions" / f"draw_{d:03d}", ss, sims, person.name, d)
        values[d] = [row[str(t)][k] for t, k in cols]
        if d < keep:
            kept.append(row)
    if values_out is not None:
        values_out.update({col: values[:, j] for j, col in enumerate(cols)})
    gamma, bands, ps = judge(values, np.array([real_stats[t][k] for t, k in cols]), level)
    checks: list[Check] = []
    for t in tasks:
        for k in STATISTICS:
            why = simulated(person, k)
            r = real_stats[t][k]
            if why:
                checks.append(Check(t, k, r, None, None, None, None, why))
                continue
            j = cols.index((t, k))
            col = values[:, j]
            med = float(np.nanmedian(col)) if np.isfinite(col).any() else math.nan
            p = float(ps[j])
            band = (float(bands[j, 0]), float(bands[j, 1]))
            ok = bool(math.isfinite(p) and p >= gamma)
            checks.append(Check(t, k, r, med, band, p, ok))
    j_checks = len(cols)
    return {
        "person": person.name,
        "draws": draws,
        "seed": seed,
        "band": {
            "level": level,
            "checks": j_checks,
            "gamma": _num(gamma),
            "bonferroni_gamma": (1.0 - level) / j_checks if j_checks else None,
            "min_draws": min_draws(j_checks, level),
            "rule": "joint (min-p), the real value ranked as one more replicate: each of the "
            "S + 1 values' two-sided rank p-value per check among all S + 1, itself counted; "
            "gamma the (floor((1 - level)(S + 1)) + 1)-th smallest of their smallest p over "
            "all checks; a check passes when the real value's p is at least gamma (at most "
            "1 - level of exchangeable values fail any)",
        },
        "checks": [c.to_json() for c in checks],
        "failed": sum(1 for c in checks if c.passed is False),
        "passed": sum(1 for c in checks if c.passed is True),
        "kept_replicates": kept,
    }


def write_replicate(
    folder: Path,
    real: Sequence[Session],
    sims: Sequence[Sequence[dict[str, Any]]],
    person: str,
    draw: int,
) -> None:
    """The replicate's sessions as session logs in import-study's format (each real log's
    header and episode, the corrections replaced, ``extra["simulated"]`` saying by whom)."""
    from strol_gym.wrappers.session_log import SessionWriter

    folder.mkdir(parents=True, exist_ok=True)
    for s, rows in zip(real, sims, strict=True):
        header = {k: v for k, v in s.header.items() if k not in ("type", "format", "version")}
        extra = dict(header.get("extra") or {})
        extra["simulated"] = {"person": person, "draw": draw, "real_log": s.name}
        header["extra"] = extra
        writer = SessionWriter(folder / s.name, header)
        try:
            ep = {k: v for k, v in s.episode.items() if k != "type"}
            ep["path_samples"] = _length(s, rows[0]) if rows else s.path_samples
            ep["corrections_logged"] = len(rows)
            ep["corrections_empty"] = ep["corrections_one_pose"] = 0
            writer.episode(**ep)
            for i, c in enumerate(rows):
                where = c.get("path_sample")
                writer.correction(
                    index=i,
                    step=where,
                    x=np.asarray(c["x"]),
                    u_h=np.asarray(c["u_h"]),
                    u_r=np.asarray(c["u_r"]),
                    theta_hat_before=None,
                    theta_hat_after=None,
                    path_sample=where,
                    path_samples=_length(s, c),
                    correction_time=None,
                )
            writer.end(reason="simulated session", interrupted=False, corrections=len(rows))
        finally:
            writer.close()


# ---------------------------------------------------------------------------- output
LABELS = {
    "count_one": "corrections / session, One",
    "count_mof": "corrections / session, MOF",
    "count_strol": "corrections / session, StROL",
    "when_median": "median start along the path (share)",
    "size_median": "median ‖u_H / a_max‖",
    "size_small": "share < 0.7 a_max",
    "angle_median": "median angle to θ*'s steepest ascent (°)",
    "angle_over_90": "share > 90°",
    "raised": "share raising θ*·φ",
}


def markdown(report: dict[str, Any]) -> str:
    """The report's table."""
    band = report["band"]
    lines = [
        f"# check-human: {report['person']}",
        "",
        f"{report['draws']} replicates (seed {report['seed']}); joint {band['level']:.0%} band "
        f"over {band['checks']} checks (γ = {_fmt(band['gamma'])}, Bonferroni's "
        f"{_fmt(band['bonferroni_gamma'])}): {report['passed']} pass, {report['failed']} fail.",
        "",
        "| Task | statistic | real | simulated median | band | p | |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in report["checks"]:
        verdict = {True: "pass", False: "**FAIL**", None: "n/a"}[c["pass"]]
        band_s = "" if c["band"] is None else f"[{_fmt(c['band'][0])}, {_fmt(c['band'][1])}]"
        lines.append(
            f"| {c['task']} | {LABELS[c['statistic']]} | {_fmt(c['real'])} | "
            f"{_fmt(c['simulated_median'])} | {band_s} | {_fmt(c['p'])} | {verdict} |"
        )
    notes = sorted({c["note"] for c in report["checks"] if c["note"]})
    return "\n".join(lines + [""] + [f"- n/a: {n}" for n in notes]) + "\n"


def _fmt(v: Any) -> str:
    if v is None:
        return "–"
    return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"


def plot(path: Path, report: dict[str, Any], values: dict[tuple[int, str], np.ndarray]) -> None:
    """One panel per Task and statistic: the replicates' spread, the band, the real value
    (red where it fails)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tasks = sorted({c["task"] for c in report["checks"]})
    fig, axes = plt.subplots(
        len(tasks),
        len(STATISTICS),
        figsize=(2.1 * len(STATISTICS), 2.0 * len(tasks)),
        squeeze=False,
    )
    for c in report["checks"]:
        ax = axes[tasks.index(c["task"]), STATISTICS.index(c["statistic"])]
        v = values.get((c["task"], c["statistic"]))
        if v is not None and np.isfinite(v).any():
            ax.hist(v[np.isfinite(v)], bins=25, color="0.75")
        if c["band"] is not None and None not in c["band"]:
            ax.axvspan(c["band"][0], c["band"][1], color="tab:blue", alpha=0.15)
        if c["real"] is not None:
            color = {True: "tab:green", False: "tab:red", None: "0.3"}[c["pass"]]
            ax.axvline(c["real"], color=color, lw=2)
        ax.set_yticks([])
        ax.tick_params(labelsize=6)
        if c["task"] == tasks[0]:
            ax.set_title(LABELS[c["statistic"]], fontsize=6)
        if c["statistic"] == STATISTICS[0]:
            ax.set_ylabel(f"Task {c['task']}", fontsize=8)
    fig.suptitle(
        f"check-human: {report['person']} (grey: replicates; band: joint "
        f"{report['band']['level']:.0%})",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def check_human(
    logs: str | Path,
    person: Person,
    out: str | Path,
    draws: int = DRAWS,
    seed: int = 0,
    keep: int = 10,
    plots: bool = True,
    level: float = LEVEL,
) -> dict[str, Any]:
    """Run the check and write OUT/report.json, report.md, check.png and the kept replicates."""
    real = read_sessions(logs)
    out = Path(out)
    values: dict[tuple[int, str], np.ndarray] = {}
    report = run_check(real, person, draws, seed, keep, out, values, level)
    out.mkdir(parents=True, exist_ok=True)  # after the checks: a refusal leaves no folder
    (out / "report.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    (out / "report.md").write_text(markdown(report), encoding="utf-8")
    if plots:
        plot(out / "check.png", report, values)
    return report


__all__ = [
    "LEARNERS",
    "STATISTICS",
    "AtLoggedMoments",
    "Person",
    "Session",
    "StudyPopulation",
    "add_parser",
    "by_task",
    "check_human",
    "command",
    "joint_band",
    "judge",
    "min_draws",
    "person_from",
    "read_sessions",
    "run_check",
    "statistics",
    "two_sided_p",
]


def add_parser(sub: Any) -> None:
    from strol_gym.benchmarks.args import plugin_option, positive_int, unit_open

    p = sub.add_parser(
        "check-human",
        help="posterior-predictive check of a simulated person against real session logs",
        description="Simulate every real session of LOGS (a folder written by strol-bench "
        "import-study) --draws times with a registered human (--human), StROL-Study-v2's "
        "fitted population (--population) or your own person (--person MODULE:ATTR), and check "
        "per study Task: corrections per session by learner, when they start along the path, "
        "the median size and share below 0.7 a_max, the median angle to θ*'s steepest ascent "
        "and share above 90°, the share raising θ*·φ. Each check passes when the real value "
        "lies in the replicates' band, the bands joint at --level (95 %%) over all checks. Writes "
        "OUT/report.json, report.md, check.png and the first --keep replicates as session logs.",
    )
    p.add_argument("logs", metavar="LOGS", help="a folder of real session logs (import-study's)")
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument(
        "--human", help="a registered human model (with its own defaults: a fit's values)"
    )
    who.add_argument("--population", action="store_true", help="StROL-Study-v2's population")
    who.add_argument("--person", metavar="MODULE:ATTR", help="your own Person (see the docs)")
    p.add_argument("--human-kwargs", default="{}", help="JSON object of the human's arguments")
    p.add_argument("--sigma", type=float, default=None, help="the human's σ (units of a_max)")
    p.add_argument("--bias", type=float, default=None, help="the human's ε (units of a_max)")
    p.add_argument("--beta", type=float, default=None, help="the human's β")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument(
        "--draws",
        type=positive_int("--draws", MAX_DRAWS, low=20),
        default=DRAWS,
        help=f"replicates ({DRAWS}; at least 2·J/(1 − level) − 1 for J checks: at 0.95, 1079 "
        "for 27, 599 for 15)",
    )
    p.add_argument(
        "--level",
        type=unit_open("--level"),
        default=LEVEL,
        help="the joint band's level: a right person fails no check in at least this share "
        f"of runs ({LEVEL})",
    )
    p.add_argument("--keep", type=positive_int("--keep", MAX_KEEP, low=0), default=10)
    p.add_argument("--seed", type=positive_int("--seed", low=0), default=0)
    p.add_argument("--no-plots", action="store_true")
    plugin_option(p)


def person_of(args: Any) -> Person:
    """The :class:`Person` the command line names."""
    if args.population:
        return StudyPopulation()
    if args.person:
        return person_from(args.person)
    from strol_gym.files import loads_json

    kwargs = loads_json(args.human_kwargs.encode(), "--human-kwargs")
    if not isinstance(kwargs, dict):
        raise ValueError("--human-kwargs must be a JSON object of the human's arguments")
    shared = {
        k: getattr(args, k) for k in ("sigma", "bias", "beta") if getattr(args, k) is not None
    }
    from strol_gym.humans import check_human_kwargs

    return AtLoggedMoments(args.human, **shared, **check_human_kwargs(args.human, kwargs))


def command(args: Any, parser: Any) -> int:
    try:
        person = person_of(args)
        report = check_human(
            args.logs,
            person,
            args.out,
            args.draws,
            args.seed,
            args.keep,
            not args.no_plots,
            args.level,
        )
    except ValueError as e:
        parser.error(str(e))
    print(markdown(report))
    print(f"wrote {Path(args.out) / 'report.json'}")
    return 0
