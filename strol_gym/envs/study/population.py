"""The fitted study population: StROL-Study-v2's default participant ("fitted"), read from
the shipped fit file ``participant_fit.json`` beside this module.

**Source.** The authors' user study: 12 people × 3 Tasks × 3 learners = 108 sessions of
physical corrections (github.com/VT-Collab/StROL_RAL, the tree before commit ``d383bef``),
imported with ``strol-bench import-study DATA --out LOGS`` and fitted with

    strol-bench fit-participant LOGS --out strol_gym/envs/study/participant_fit.json

on 2026-11-25 (``benchmarks/sessions/fit_participant.py``; the file's ``command`` and
``date`` say the same). Only fitted numbers are shipped: no session, no correction.

**What is fitted** (each a between-person distribution: a person's own value, then a normal
on a log scale over the twelve; 95 % intervals by resampling people; leave-one-person-out
held-out log-likelihoods in the file): corrections per session (per-Task means and a person's
multiplier), a correction's displacement and rotation (a person's median and the spread about
it), its aim against θ*'s best correction (τ: the direction is b̂ + τ z, matched to the
person's median cosine at its own poses), and when the person is done (``linger``: after the
last correction it watches this share of the session so far; from where the last correction
fell along the path). **What is not fitted** (the logs hold no time and no force): reaction
time, how a push is held and released, the rest between pushes, the push's force and the
judging of the robot's motion: :data:`PRIORS`, each marked "prior, not fitted" with its
source, in the file and in docs/study.md.

A simulated user draws its own parameters (:meth:`Population.draw`) from its own generator:
twenty users are twenty people, the same seed the same person.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym import checks
from strol_gym.envs.study.people import CORRECTIONS, FittedParams
from strol_gym.files import loads_json, read_regular
from strol_gym.humans.aim import aim_direction, aimed_corrections, fitted_aim_params
from strol_gym.humans.interface import DEFAULT_CANDIDATES, Draws, HumanModel
from strol_gym.humans.timing import hazard_vector
from strol_gym.tasks.base import Task
from strol_gym.tasks.study import StudyTask

FIT_FILE = Path(__file__).with_name("participant_fit.json")
"""The shipped fit (module docstring)."""
TIMING_FILE = Path(__file__).with_name("timing_fit.json")
"""The shipped timing hazard (``strol-bench fit-timing``): when a person steps in."""
SHIPPED_CORRECTION = "aimed"
"""The shipped population's model of a correction: the aimed person fitted per Task (better
held-out likelihood than the scale-free fit on every Task, docs/humans.md)."""
FORMAT = "strol-participant-fit"
TIMING_FORMAT = "strol-timing-fit"
MAX_FIT_BYTES = 1_000_000
"""A fit file larger than this is refused before it is read."""
MAX_READ_SCALE = 10.0
"""The largest ``FittedPopulationModel`` ``read_scale`` accepted (read over intended)."""

FITTED = (
    "size_log_mean",
    "size_log_sd",
    "size_within",
    "turn_log_mean",
    "turn_log_sd",
    "turn_within",
    "aim_log_mean",
    "aim_log_sd",
    "linger_log_mean",
    "linger_log_sd",
    "count_person_sd",
)
"""The fitted scalars (each ``{"estimate", "ci95"}`` in the file), besides ``count_mean``."""

PRIORS: dict[str, dict[str, Any]] = {
    "reaction": {
        "value": 0.4,
        "unit": "s",
        "source": "Card, Moran & Newell (1983), The Psychology of Human-Computer Interaction, "
        "ch. 2: a perceive-decide-act cycle of 240 ms [105-470 ms]; 0.4 s within it, a "
        "choice (where to push) on top of a simple reaction",
    },
    "max_push": {
        "value": 2.0,
        "unit": "s",
        "source": "hand-set (v1's participant); no measured push duration found: the logs "
        "hold no time. Most pushes end earlier, at the target or when the arm stops giving",
    },
    "ramp": {
        "value": 0.2,
        "unit": "s",
        "source": "hand-set (v1's participant): the force rises and falls over 0.2 s",
    },
    "rest": {
        "value": 1.5,
        "unit": "s",
        "source": "hand-set (v1's participant): after a push it watches 1.5 s before judging "
        "again (above the 0.5 s hold-off that ends a correction)",
    },
    "push_force": {
        "value": 35.0,
        "unit": "N",
        "source": "the most it pushes: a push's force is feel x the intended displacement (the "
        "median 11 cm: 43 N), capped at 35 N: on v2's arm (300 N/m) that holds the cup up to "
        "about 12 cm off its setpoint, and pushes of 40-60 N tripped v2's joint-torque reflex "
        "(1 push in 5 lost; with the cap 1 in 20, Tasks 1-2, docs/study.md); v1's participant "
        "pushed with 60 N. Not fitted (no force logged)",
    },
    "push_torque": {
        "value": 6.0,
        "unit": "N m",
        "source": "the most it twists; a push's torque is feel_rot x the intended turn (the "
        "median 7°: 1.6 N m); not fitted",
    },
    "feel": {
        "value": 390.0,
        "unit": "N/m",
        "source": "1.3x v2's stiffness (300 N/m): a person pushing a spring feels how hard to "
        "push, and holds it a little past the target; not fitted (no force logged)",
    },
    "feel_rot": {
        "value": 13.0,
        "unit": "N m/rad",
        "source": "1.3x v2's rotational stiffness (10 N m/rad), as feel; not fitted",
    },
    "min_felt": {
        "value": 20.0,
        "unit": "N",
        "source": "the least push that is a correction (15 N, the logs' threshold too) with a "
        "margin; not fitted",
    },
    "threshold": {
        "value": 0.7,
        "unit": "score",
        "source": "the acceptance threshold on the motion's score (v1's: 0.4), raised so that "
        "Task 1's corrections per session come near the real mean (calibrated on seeds "
        "39200-39203 with One, MOF and StROL, outside the study's); not identified by the logs "
        "(no θ̂ per correction)",
    },
    "patience": {
        "value": 10,
        "unit": "pushes",
        "source": "v1's give-up rule kept loose (v1: 3): when a person is done is the fitted "
        "budget; it still gives up after 10 pushes that bring no better motion",
    },
}
"""Parameters the logs do not identify: prior, not fitted (each with its source)."""


@dataclasses.dataclass(frozen=True)
class Population:
    """The fitted between-person distribution (:data:`FIT_FILE`)."""

    count_mean: dict[int, float]
    """Corrections per session, per Task (the mean over people and learners)."""
    fitted: dict[str, float]
    """The :data:`FITTED` estimates."""
    priors: dict[str, Any]
    """The :data:`PRIORS` values the file names (``patience`` an int)."""
    hazard: dict[int, tuple[float, ...]] | None = None
    """Per Task, the timing hazard's (a, b, c[, d]) (``FittedParams.hazard``); None: the
    budget."""
    path_time: dict[int, float] | None = None
    """Per Task, the s of the robot's motion a person watches (with ``hazard``)."""
    doubled_budget: dict[int, float] | None = None
    """Per Task whose session ended on the authors' doubled count (``timing.DOUBLED_TASKS``),
    the budget (s): the person is done when the robot's motion plus its motion before the
    last correction reaches it (in place of ``path_time``)."""
    correction: str = "population"
    """Its people's model of a correction (``FittedParams.correction``)."""
    rise: float | None = None
    """s over which a push's force rises (and falls): the median logged samples per real
    correction × 0.05 s (the authors' loop logged a sample at each new force maximum), in
    place of the prior ``ramp``; None: the prior."""

    def draw(self, rng: np.random.Generator, task: int) -> FittedParams:
        """One person for a session of Task ``task`` (1-3), from ``rng``: its sizes, aim,
        linger and when it steps in: the timing hazard of its Task where the population has
        one (then it reacts to the robot), else a budget (Poisson of the Task's mean times its
        own multiplier)."""
        f = self.fitted
        task = int(checks.number("task", task, low=1, high=3, integer=True))
        z = rng.standard_normal(5)
        sd_r = f["count_person_sd"]
        multiplier = math.exp(sd_r * z[4] - 0.5 * sd_r**2)  # mean 1
        when: dict[str, Any] = {}
        if self.hazard is not None and self.path_time is not None:
            when = {"hazard": self.hazard[task], "path_time": self.path_time[task]}
            if self.doubled_budget and task in self.doubled_budget:
                when["path_time"] = math.inf
                when["doubled_budget"] = self.doubled_budget[task]
            if self.rise is not None:
                when["ramp"] = self.rise
        else:
            when = {"budget": int(rng.poisson(self.count_mean[task] * multiplier))}
        when["correction"] = self.correction
        return FittedParams(
            size=math.exp(f["size_log_mean"] + f["size_log_sd"] * z[0]),
            size_within=f["size_within"],
            turn=math.exp(f["turn_log_mean"] + f["turn_log_sd"] * z[1]),
            turn_within=f["turn_within"],
            aim=math.exp(f["aim_log_mean"] + f["aim_log_sd"] * z[2]),
            linger=math.exp(f["linger_log_mean"] + f["linger_log_sd"] * z[3]),
            **{**self.priors, **when},
        )


def parse(obj: Any, what: str = "participant fit") -> Population:
    """A :class:`Population` from a fit file's JSON object (every field checked)."""
    if not isinstance(obj, dict) or obj.get("format") != FORMAT:
        raise ValueError(f"{what} must be a JSON object with format {FORMAT!r}")
    fitted = checks.mapping(f"{what}['fitted']", obj.get("fitted"), "an object")
    est: dict[str, float] = {}
    for name in FITTED:
        entry = checks.mapping(f"{what}['fitted'][{name!r}]", fitted.get(name), "an object")
        low = 0.0 if name.endswith(("_sd", "_within")) else None
        est[name] = float(
            checks.number(f"{what}['fitted'][{name!r}]['estimate']", entry.get("estimate"), low=low)
        )
    counts = checks.mapping(
        f"{what}['fitted']['count_mean']", fitted.get("count_mean"), "an object"
    )
    count_mean = {}
    for t in (1, 2, 3):
        entry = checks.mapping(f"{what}['fitted']['count_mean']['{t}']", counts.get(str(t)))
        count_mean[t] = float(
            checks.number(
                f"{what}['fitted']['count_mean']['{t}']['estimate']",
                entry.get("estimate"),
                low=0.0,
                high=1000.0,
            )
        )
    prior = checks.mapping(f"{what}['prior']", obj.get("prior"), "an object")
    priors = {}
    for name in PRIORS:
        entry = checks.mapping(f"{what}['prior'][{name!r}]", prior.get(name), "an object")
        value = checks.number(f"{what}['prior'][{name!r}]['value']", entry.get("value"), low=0.0)
        priors[name] = value if isinstance(PRIORS[name]["value"], int) else float(value)
    return Population(count_mean, est, priors)


def parse_timing(
    obj: Any, what: str = "timing fit"
) -> tuple[dict[int, tuple[float, ...]], dict[int, float], float]:
    """Per Task (a, b, c[, d]) and path time, and the push's rise time, from a timing fit file's
    JSON object (checked)."""
    if not isinstance(obj, dict) or obj.get("format") != TIMING_FORMAT:
        raise ValueError(f"{what} must be a JSON object with format {TIMING_FORMAT!r}")
    hz = checks.mapping(f"{what}['hazard']", obj.get("hazard"), "an object")
    pt = checks.mapping(f"{what}['path_time']", obj.get("path_time"), "an object")
    hazard, path_time = {}, {}
    for t in (1, 2, 3):
        hazard[t] = hazard_vector(f"{what}['hazard']['{t}']", hz.get(str(t)))
        path_time[t] = float(
            checks.number(f"{what}['path_time']['{t}']", pt.get(str(t)), low=0.0, low_open=True)
        )
    rise = float(checks.number(f"{what}['rise']", obj.get("rise"), low=0.01, high=10.0))
    return hazard, path_time, rise


def parse_doubled(obj: dict[str, Any], what: str = "timing fit") -> dict[int, float]:
    """Per Task its ``doubled_budget`` (s) from a timing fit's JSON object (none: {})."""
    raw = obj.get("doubled_budget", {})
    got = checks.mapping(f"{what}['doubled_budget']", raw, "an object")
    out = {}
    for key, v in got.items():
        if key not in ("1", "2", "3"):
            raise ValueError(f"{what}['doubled_budget']: Tasks are '1'-'3', got {key!r}")
        out[int(key)] = float(
            checks.number(f"{what}['doubled_budget'][{key!r}]", v, low=1.0, high=3600.0)
        )
    return out


def _read_json(path: Path, what: str) -> Any:
    return loads_json(read_regular(path, MAX_FIT_BYTES, f"{what} file"), str(path))


def read_fit(
    path: str | Path, timing: str | Path | None = None, correction: str = "population"
) -> Population:
    """The population of fit file ``path`` (size-capped, plain JSON, checked), reacting to the
    robot with the timing fit ``timing`` if given (else it keeps a budget), its corrections by
    ``correction`` (``people.CORRECTIONS``)."""
    if correction not in CORRECTIONS:
        raise ValueError(f"correction must be one of {', '.join(CORRECTIONS)}, got {correction!r}")
    path = Path(path)
    pop = dataclasses.replace(
        parse(_read_json(path, "participant fit"), str(path)), correction=correction
    )
    if timing is None:
        return pop
    obj = _read_json(Path(timing), "timing fit")
    hazard, path_time, rise = parse_timing(obj, str(timing))
    doubled = parse_doubled(obj, str(timing))
    return dataclasses.replace(
        pop, hazard=hazard, path_time=path_time, rise=rise, doubled_budget=doubled
    )


@functools.cache
def shipped() -> Population:
    """The shipped fit with its timing hazard and the aimed person's corrections (read once
    per process)."""
    return read_fit(FIT_FILE, TIMING_FILE, SHIPPED_CORRECTION)


def best_correction(task: StudyTask, theta_star: np.ndarray, x: np.ndarray) -> np.ndarray:
    """θ*'s steepest ascent at pose ``x`` in a_max units (a_max ⊙ ∇ₓ(θ*·φ)): the direction
    the fit measures a person's aim against, the fitted participant aims from and the ĝ
    training human corrects along. ``x`` one pose (s,) or a batch (n, s), ``theta_star`` (d,)
    or one per pose (n, d); one contraction for both, so a pose's direction is the same bits
    alone or in a batch."""
    jac = task.feature_jacobian(np.asarray(x, dtype=np.float64))  # (..., d, s)
    grad = np.einsum("...ds,...d->...s", jac, np.asarray(theta_star, dtype=np.float64))
    return grad[..., : task.action_dim] * task.a_max


def draw_corrections(
    best: np.ndarray,
    rng: np.random.Generator,
    *,
    aim: float | np.ndarray,
    size: float | np.ndarray,
    size_within: float,
    turn: float | np.ndarray = 1.0,
    turn_within: float = 0.0,
) -> np.ndarray:
    """Corrections (n, a) in a_max units at poses whose θ*'s steepest ascent (in a_max units)
    is ``best`` (n, a), drawn from ``rng``: :func:`shape_corrections` of standard normals."""
    best = np.atleast_2d(np.asarray(best, dtype=np.float64))
    n, a = best.shape
    z = rng.standard_normal((n, a + 2))
    return shape_corrections(
        best, z, aim=aim, size=size, size_within=size_within, turn=turn, turn_within=turn_within
    )


def shape_corrections(
    best: np.ndarray,
    z: np.ndarray,
    *,
    aim: float | np.ndarray,
    size: float | np.ndarray,
    size_within: float,
    turn: float | np.ndarray = 1.0,
    turn_within: float = 0.0,
) -> np.ndarray:
    """The fitted model of a correction, given its standard normals ``z`` (n, a + 2): the
    direction b̂ + ``aim``·z[:, :a]; the position part scaled to a log-normal length (median
    ``size``, log sd ``size_within``, from z[:, a]), the rotation part (a = 6) to one of median
    ``turn`` (from z[:, a + 1]). Per-row parameters may be arrays (n,). The participant's
    choice, the fit's model and the ĝ training's human: one function."""
    best = np.atleast_2d(np.asarray(best, dtype=np.float64))
    n, a = best.shape
    col = np.reshape  # per-row parameters as columns

    def per_row(v: float | np.ndarray) -> np.ndarray:
        return col(np.broadcast_to(np.asarray(v, dtype=np.float64), (n,)), (n, 1))

    unit = best / np.maximum(np.linalg.norm(best, axis=1, keepdims=True), 1e-12)
    d = unit + per_row(aim) * z[:, :a]
    out = np.empty_like(d)
    lengths = per_row(size) * np.exp(size_within * z[:, a : a + 1])
    pos = d[:, :3]
    out[:, :3] = pos / np.maximum(np.linalg.norm(pos, axis=1, keepdims=True), 1e-12) * lengths
    if a > 3:
        rot = d[:, 3:]
        turns = per_row(turn) * np.exp(turn_within * z[:, a + 1 : a + 2])
        out[:, 3:] = rot / np.maximum(np.linalg.norm(rot, axis=1, keepdims=True), 1e-12) * turns
    return out


def aimed_draws(
    task: StudyTask, theta_star: np.ndarray, x: np.ndarray, z: np.ndarray, pick: np.ndarray
) -> np.ndarray:
    """Corrections (n, a) in a_max units of the aimed person fitted for ``task``'s study Task
    (``humans.aim.FITTED_AIM``) at poses ``x`` (n, s), from standard normals ``z`` (n, a + 1)
    and uniforms ``pick`` (n,): about the aimed person's direction for θ* ⊙ its emphasis
    (``humans.aim.aim_direction``, with its fitted ``reach``)."""
    return aimed_at(aimed_aim(task, theta_star, x), z, pick, task)


def aimed_aim(task: StudyTask, theta_star: np.ndarray, x: np.ndarray) -> np.ndarray:
    """b̂ (n, a): what the aimed person fitted for ``task`` aims at, at poses ``x`` (n, s), for
    θ* ⊙ its emphasis (``humans.aim.aim_direction`` with its fitted ``reach``). Row by row:
    what a pose gives does not depend on the others in the batch, so it may be computed once
    per pose and reused (:func:`aimed_at`)."""
    kw = fitted_aim_params(task)
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    star = np.broadcast_to(
        np.asarray(theta_star, dtype=np.float64) * kw["emphasis"], (len(x), task.dim)
    )
    return aim_direction(task, x, np.zeros((len(x), task.action_dim)), star, kw["reach"])


def aimed_at(best: np.ndarray, z: np.ndarray, pick: np.ndarray, task: StudyTask) -> np.ndarray:
    """:func:`aimed_draws` given its aims ``best`` (:func:`aimed_aim`)."""
    kw = {k: v for k, v in fitted_aim_params(task).items() if k not in ("emphasis", "reach")}
    return aimed_corrections(best, z, pick, **kw)


def aimed_correction(
    task: StudyTask, theta_star: np.ndarray, x: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """One aimed correction (a,) at pose ``x`` (a_max units), its draws from ``rng``."""
    z = rng.standard_normal((1, task.action_dim + 1))
    return aimed_draws(task, theta_star, x, z, rng.random(1))[0]


def cosine(u: np.ndarray, best: np.ndarray) -> np.ndarray:
    """cos(u, best) row by row, both in a_max units (NaN where either is zero): the data
    card's "cos(u_H, θ*'s best correction)"."""
    u, best = np.atleast_2d(u), np.atleast_2d(best)
    den = np.linalg.norm(u, axis=1) * np.linalg.norm(best, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, np.einsum("ij,ij->i", u, best) / den, np.nan)


class FittedPopulationModel(HumanModel):
    """The fitted population's corrections as a human model (``strol-bench train --human
    strol_gym.envs.study.population:FittedPopulationModel``, the v2 study ĝ's training human):
    each correction by its own person drawn from the shipped fit, in the participant's way
    (:func:`shape_corrections` at θ*'s steepest ascent), unclipped (v2 reads pushes past
    a_max as they are). ``read_scale`` (position, rotation) scales what the person meant to
    what v2's arm reads of it (the learner's input at run time: the median read u_H over the
    median intended correction, measured by ``participant_check``; docs/study.md), so that
    ĝ trains at the run-time scale. σ and ε add to it (default 0: the aim is the fitted
    noise)."""

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        n_candidates: int = DEFAULT_CANDIDATES,
        read_scale: Sequence[float] = (1.0, 1.0),
        correction: str = "population",
    ) -> None:
        if correction not in CORRECTIONS:
            raise ValueError(
                f"correction must be one of {', '.join(CORRECTIONS)}, got {correction!r}"
            )
        self.correction = correction
        if not isinstance(task, StudyTask):
            raise ValueError(f"task must be a study Task, got {type(task).__name__}")
        super().__init__(task, sigma, bias, n_candidates)
        scale = checks.vector("read_scale", read_scale, 2)
        for name, v in zip(("read_scale[0]", "read_scale[1]"), scale.tolist(), strict=True):
            checks.number(name, v, low=0.0, high=MAX_READ_SCALE, low_open=True)
        self.read_scale = (float(scale[0]), float(scale[1]))
        self.study_task: StudyTask = task
        self.fit = shipped()

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        a = self.task.action_dim
        out = {"person": rng.standard_normal((n, 3)), "z": rng.standard_normal((n, a + 2))}
        if self.correction == "aimed":
            out["pick"] = rng.random(n)
        return out

    def choose(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_star: np.ndarray,
        draws: Draws,
        theta_hat: np.ndarray | None = None,
        k: np.ndarray | int = 0,
    ) -> np.ndarray:
        task, f = self.study_task, self.fit.fitted
        if self.correction == "aimed":
            z1 = draws.extra["z"][:, : task.action_dim + 1]
            u = aimed_draws(task, theta_star, x, z1, draws.extra["pick"])
            return self._read(u) * task.a_max
        best = best_correction(task, theta_star, x)
        z = draws.extra["person"]
        u = shape_corrections(
            best,
            draws.extra["z"],
            aim=np.exp(f["aim_log_mean"] + f["aim_log_sd"] * z[:, 0]),
            size=np.exp(f["size_log_mean"] + f["size_log_sd"] * z[:, 1]),
            size_within=f["size_within"],
            turn=np.exp(f["turn_log_mean"] + f["turn_log_sd"] * z[:, 2]),
            turn_within=f["turn_within"],
        )
        return self._read(u) * task.a_max

    def _read(self, u: np.ndarray) -> np.ndarray:
        """``u`` scaled by ``read_scale`` (position, rotation), in place."""
        u[:, :3] *= self.read_scale[0]
        u[:, 3:] *= self.read_scale[1]
        return u


__all__ = [
    "FITTED",
    "FIT_FILE",
    "PRIORS",
    "SHIPPED_CORRECTION",
    "TIMING_FILE",
    "FittedPopulationModel",
    "Population",
    "aimed_aim",
    "aimed_at",
    "aimed_correction",
    "aimed_draws",
    "cosine",
    "draw_corrections",
    "parse",
    "parse_doubled",
    "read_fit",
    "shape_corrections",
    "shipped",
]
