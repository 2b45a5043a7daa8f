"""The aimed person: a correction as a direction and a size, each with its own noise.

Per-axis Gaussian noise (δ ~ N(ε a_max, (σ a_max)²) on a chosen candidate) ties a correction's
size to its aim: to make small pushes it must shrink the choice, and to make them well aimed
its σ must be small, which makes large pushes rare. The twelve people of the authors' study did
both: about a fifth of their corrections were below 0.7 a_max, and about 83 % raised θ*'s reward.
This model separates the two (all in units of a_max per axis):

- **where it pushes**: about b̂, what it aims at (:func:`aim_direction`): the steepest ascent
  (:func:`steepest_ascent`) of θ* ⊙ w, the preference with each feature weighed by the person's
  ``emphasis`` w, or, with ``reach`` r > 0, the direction of the best push of length r (a push of
  a hand's length gains by the features' curvature too); with an aim error in the direction:
  y = D (b̂ + τ z), z ~ N(0, I), d = y / ‖y‖ (a projected normal: τ = 0 pushes along D b̂, τ → ∞
  anywhere), where D weighs the axes after the first three (the study Tasks' rotation) by
  ``turn`` = ρ: the people turned the cup much less than θ*'s steepest ascent in units of a_max
  asks (its rotation is about 85 % of its length; theirs about 40 %);
- **how far**: a log-normal length r, median ``size`` and log sd ``size_sd``; with probability
  ``small_share`` from a second log-normal of median ``small_size`` (same log sd): the data
  choose one size or two (held-out likelihood, :data:`FITTED_AIM`);
- u_H = r d, then the shared δ (σ = ε = 0 by default: the noise is in the aim and the size).

API (one place each):

- :class:`AimedModel` (registered ``aimed``): the model, parameters ``aim`` (τ), ``turn`` (ρ),
  ``size``, ``size_sd``, ``small_share``, ``small_size``, ``emphasis`` (w, one per feature),
  ``reach`` besides σ, ε; ``AimedModel(task, **params).correct(x, u_r, theta_star, rng)`` gives
  a batch of corrections (the :class:`HumanModel` interface);
- :class:`FittedAimedModel` (registered ``fitted-aimed``): its maximum-likelihood values per
  study Task (:data:`FITTED_AIM`, fitted by ``strol-bench fit-human --human aimed``; in another
  Task, Task 3's); :func:`fitted_aim_params` the same values as keyword arguments;
- :func:`aimed_corrections`: the corrections (n, a) from parameters and standard draws (what
  both the model and a person elsewhere, e.g. the study population, call);
- :func:`log_density`: log p(u_H) of corrections under the model (what ``fit-human`` maximises:
  ``strol_gym.benchmarks.sessions.fitting.Aimed``);
- :func:`steepest_ascent`, :func:`aim_direction`: b and b̂ at a batch of states.

The direction's density on the unit sphere is the projected normal's: with y ~ N(μ, Σ),
μ = D b̂, Σ = τ² D², A = dᵀΣ⁻¹d, s = dᵀΣ⁻¹μ / √A,
p(d) = (2π)^(−a/2) |Σ|^(−1/2) A^(−a/2) e^(−μᵀΣ⁻¹μ/2) Γ(a) e^(s²/4) D_(−a)(−s)
(D_ν the parabolic cylinder function); u_H's density is p(r) p(d) / r^(a−1).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from strol_gym import checks
from strol_gym.humans.checks import check_fraction
from strol_gym.humans.interface import DEFAULT_CANDIDATES, Draws, HumanModel
from strol_gym.humans.zoo import check_probability
from strol_gym.lazy import LazyModule
from strol_gym.tasks.base import Task
from strol_gym.tasks.study import StudyTask, study_task_name

if TYPE_CHECKING:
    from scipy import special
else:  # scipy loads at the first density: importing strol_gym does not need it
    special = LazyModule("scipy.special")

MAX_AIM = 20.0
"""The largest τ accepted: beyond it the direction is uniform to within 0.3 % in density."""
MIN_AIM = 0.05
"""The smallest τ the density is computed for (the parabolic cylinder function stays finite);
a smaller τ still draws, it is only not fittable."""
MAX_TURN = 10.0
"""The largest rotation weight ρ accepted."""
MAX_SIZE = 100.0
"""The largest median length accepted (units of a_max)."""
STEP = 1e-6
"""The finite-difference step (units of a_max) of :func:`steepest_ascent`."""
TURN_AXES = 3
"""The axes from this one on are weighed by ``turn`` (the study Tasks' rotation)."""


def steepest_ascent(task: Task, x: np.ndarray, u_r: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """b (n, a) in units of a_max: the direction that raises θ·φ fastest per unit of
    a_max-scaled push. A Task with ``feature_jacobian`` whose state begins with the action's
    coordinates (the study Tasks): a_max ⊙ ∇ₓ(θ·φ) at the pose after u_R (unclipped by the
    planner's box: the person does not know it); any other Task: a_max ⊙ ∂(θ·g(x, u, u_R))/∂u
    at u = 0 by central differences (g the Task's own)."""
    x, u_r, theta = (np.atleast_2d(np.asarray(v, dtype=np.float64)) for v in (x, u_r, theta))
    n, a = len(x), task.action_dim
    bound = np.asarray(task.action_bound, dtype=np.float64)
    if isinstance(task, StudyTask):
        jac = task.feature_jacobian(x + np.pad(u_r, ((0, 0), (0, x.shape[1] - a))))
        return np.einsum("nds,nd->ns", jac, theta)[:, :a] * bound
    return push_gradient(task, x, u_r, theta, np.zeros((n, a)), STEP)


def push_gradient(
    task: Task, x: np.ndarray, u_r: np.ndarray, theta: np.ndarray, at: np.ndarray, step: float
) -> np.ndarray:
    """∂(θ·g(x, u, u_R))/∂u at u = ``at`` (n, a), both in units of a_max, by central
    differences of ``step`` (the Task's own g)."""
    a = at.shape[1]
    bound = np.asarray(task.action_bound, dtype=np.float64)
    steps = np.concatenate([np.eye(a), -np.eye(a)]) * step  # (2a, a)
    u = (at[:, None, :] + steps[None]) * bound
    g = task.g(x[:, None, :], u, u_r[:, None, :])
    r = np.einsum("nkd,nd->nk", g, theta)
    return (r[:, :a] - r[:, a:]) / (2.0 * step)


REACH_STEPS = 20
"""Ascent steps of :func:`aim_direction` on the sphere of radius ``reach``."""
REACH_RATE = 0.5
"""Each step's turn toward the tangent of θ·g's gradient (as a share of the unit direction)."""


def aim_direction(
    task: Task, x: np.ndarray, u_r: np.ndarray, theta: np.ndarray, reach: float
) -> np.ndarray:
    """b̂ (n, a), unit rows in units of a_max (zero where θ·φ is flat): the direction a person
    aims at. ``reach`` 0: θ's steepest ascent (:func:`steepest_ascent`); ``reach`` r > 0: the
    direction of the best push of length r (θ·g(x, r d, u_R) over unit d, the Task's own g),
    by :data:`REACH_STEPS` ascent steps on the sphere from the steepest ascent, the best
    direction met kept (so never worse than the steepest ascent for that push): a push of a
    hand's length gains by the features' curvature too (a distance grows whichever way one
    moves off it; uprightness falls whichever way one tilts)."""
    x, u_r, theta = (np.atleast_2d(np.asarray(v, dtype=np.float64)) for v in (x, u_r, theta))
    d = unit_rows(steepest_ascent(task, x, u_r, theta))
    if reach <= 0.0:
        return d
    moving = np.any(d != 0.0, axis=1, keepdims=True)
    bound = np.asarray(task.action_bound, dtype=np.float64)

    def value(dirs: np.ndarray) -> np.ndarray:
        return np.einsum("nd,nd->n", task.g(x, reach * dirs * bound, u_r), theta)

    best, best_value = d, value(d)
    for _ in range(REACH_STEPS):
        grad = push_gradient(task, x, u_r, theta, reach * d, 1e-4)
        tangent = grad - np.einsum("na,na->n", grad, d)[:, None] * d
        norm = np.linalg.norm(grad, axis=1, keepdims=True)
        turn = np.divide(tangent, norm, out=np.zeros_like(tangent), where=norm > 0)
        d = np.where(moving, unit_rows(d + REACH_RATE * turn), d)
        now = value(d)
        better = now > best_value  # kept only where it gains: never worse than the start
        best = np.where(better[:, None], d, best)
        best_value = np.maximum(now, best_value)
    return best


def unit_rows(v: np.ndarray) -> np.ndarray:
    """Each row over its norm (a zero row stays zero)."""
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, norm, out=np.zeros_like(v), where=norm > 0)


def _weights(a: int, turn: float) -> np.ndarray:
    """D's diagonal (a,): 1 on the first :data:`TURN_AXES` axes, ``turn`` after."""
    w = np.ones(a)
    w[TURN_AXES:] = turn
    return w


def aimed_corrections(
    best: np.ndarray,
    z: np.ndarray,
    pick: np.ndarray,
    *,
    aim: float,
    turn: float,
    size: float,
    size_sd: float,
    small_share: float = 0.0,
    small_size: float = 1.0,
) -> np.ndarray:
    """Corrections (n, a) in units of a_max at steepest ascents ``best`` (n, a), from standard
    normals ``z`` (n, a + 1: the direction's, then the length's) and uniforms ``pick`` (n,:
    which size). A zero ``best`` (nothing to gain) gives the direction D z."""
    best = np.atleast_2d(best)
    a = best.shape[1]
    d = unit_rows(_weights(a, turn) * (unit_rows(best) + aim * z[:, :a]))
    median = np.where(np.reshape(pick, (-1,)) < small_share, small_size, size)
    return d * (median * np.exp(size_sd * z[:, a]))[:, None]


def log_direction_density(d: np.ndarray, mu: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """log p(d) (n,) of unit directions ``d`` (n, a) for y ~ N(``mu`` (n, a), diag(``scale``²))
    (``scale`` (a,) or (n, a)), d = y / ‖y‖ (module docstring)."""
    a = d.shape[1]
    e, m = d / scale, mu / scale
    big_a = np.einsum("na,na->n", e, e)
    c = np.einsum("na,na->n", m, m)
    s = np.einsum("na,na->n", e, m) / np.sqrt(big_a)
    dv, _ = special.pbdv(-float(a), -s)
    with np.errstate(divide="ignore"):
        log_int = float(special.gammaln(a)) + s * s / 4.0 + np.log(dv)
    log_det = np.log(scale).sum(axis=-1)
    return (
        -0.5 * a * math.log(2.0 * math.pi) - log_det - 0.5 * a * np.log(big_a) - 0.5 * c + log_int
    )


def log_density(
    u: np.ndarray,
    best: np.ndarray,
    *,
    aim: float,
    turn: float,
    size: float,
    size_sd: float,
    small_share: float = 0.0,
    small_size: float = 1.0,
) -> np.ndarray:
    """log p(u) (n,) of corrections ``u`` (n, a, units of a_max) at steepest ascents ``best``;
    −inf for a zero correction (the model always pushes)."""
    u, best = np.atleast_2d(u), np.atleast_2d(best)
    a = u.shape[1]
    r = np.linalg.norm(u, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        log_r = np.log(r)
    sd = max(size_sd, 1e-6)
    parts_r = [
        math.log1p(-min(small_share, 1.0 - 1e-16)) - 0.5 * ((log_r - math.log(size)) / sd) ** 2,
        math.log(max(small_share, 1e-300)) - 0.5 * ((log_r - math.log(small_size)) / sd) ** 2,
    ]
    log_pr = special.logsumexp(np.stack(parts_r), axis=0) - log_r - math.log(sd)
    log_pr -= 0.5 * math.log(2.0 * math.pi)
    w = _weights(a, turn)
    log_pd = log_direction_density(unit_rows(u), w * unit_rows(best), max(aim, MIN_AIM) * w)
    out = log_pr + log_pd - (a - 1) * log_r
    return np.where(r > 0, out, -np.inf)


FITTED_AIM: dict[str, Any] = {
    "model": "aimed",
    "per_task": {
        "study-task1": {
            "variant": "no emphasis, one size, reach 3",
            "estimate": {
                "aim": 0.7853,
                "turn": 1.0,
                "size": 0.9497,
                "size_sd": 0.7221,
                "small_share": 0.0,
                "small_size": 1.0,
                "reach": 3.0,
            },
            "ci95": {
                "aim": [0.5278, 1.1685],
                "size": [0.6924, 1.3025],
                "size_sd": [0.5266, 0.9903],
            },
            "fixed": {"turn": 1.0, "small_share": 0.0, "small_size": 1.0, "reach": 3.0},
            "heldout_loglik": 424.36,
        },
        "study-task2": {
            "variant": "emphasis, steepest ascent",
            "estimate": {
                "aim": 0.6245,
                "turn": 0.5785,
                "size": 1.3066,
                "size_sd": 0.4524,
                "small_share": 0.1138,
                "small_size": 0.224,
                "w_plate": 1.5869,
                "w_table": 0.01,
                "w_upright": 0.1341,
                "reach": 0.0,
            },
            "ci95": {
                "aim": [0.5008, 0.7789],
                "turn": [0.4563, 0.7334],
                "size": [1.0009, 1.7055],
                "size_sd": [0.3185, 0.6427],
                "small_share": [0.0519, 0.2318],
                "small_size": [0.1211, 0.4143],
                "w_plate": [1.2274, 2.0517],
                "w_table": [0.01, 0.0412],
                "w_upright": [0.0847, 0.2121],
            },
            "fixed": {"reach": 0.0},
            "heldout_loglik": 1248.34,
        },
        "study-task3": {
            "variant": "no emphasis, reach 3",
            "estimate": {
                "aim": 0.8893,
                "turn": 0.4775,
                "size": 1.3363,
                "size_sd": 0.4422,
                "small_share": 0.1345,
                "small_size": 0.2613,
                "reach": 3.0,
            },
            "ci95": {
                "aim": [0.6919, 1.143],
                "turn": [0.3965, 0.5749],
                "size": [1.1019, 1.6207],
                "size_sd": [0.3019, 0.6477],
                "small_share": [0.0673, 0.2508],
                "small_size": [0.1118, 0.6111],
            },
            "fixed": {"reach": 3.0},
            "heldout_loglik": 1218.46,
        },
    },
    "params": {
        "aim": 0.8893,
        "turn": 0.4775,
        "size": 1.3363,
        "size_sd": 0.4422,
        "small_share": 0.1345,
        "small_size": 0.2613,
        "reach": 3.0,
    },
    "heldout_loglik_variants": {
        "study-task1": {
            "emphasis, steepest ascent": 418.22,
            "emphasis, one size, steepest ascent": 423.58,
            "no emphasis, steepest ascent": 389.13,
            "no emphasis, reach 1.3": 403.45,
            "no emphasis, reach 2": 411.35,
            "no emphasis, reach 3": 419.01,
            "no emphasis, reach 5": 424.94,
            "no emphasis, reach 8": 413.47,
            "no emphasis, one size, reach 3": 424.36,
        },
        "study-task2": {
            "emphasis, steepest ascent": 1248.34,
            "emphasis, one size, steepest ascent": 1228.57,
            "emphasis, turn 1, steepest ascent": 1189.71,
            "no emphasis, steepest ascent": 1160.11,
            "no emphasis, reach 1.3": 1197.62,
            "no emphasis, reach 2": 1215.91,
            "no emphasis, reach 3": 1233.01,
            "no emphasis, reach 5": 1250.42,
            "no emphasis, reach 8": 1244.67,
            "no emphasis, one size, reach 3": 1213.21,
        },
        "study-task3": {
            "emphasis, steepest ascent": 1172.01,
            "emphasis, one size, steepest ascent": 1149.14,
            "emphasis, turn 1, steepest ascent": 1071.65,
            "no emphasis, steepest ascent": 1169.91,
            "no emphasis, reach 1.3": 1214.16,
            "no emphasis, reach 2": 1219.46,
            "no emphasis, reach 3": 1218.46,
            "no emphasis, reach 5": 1194.99,
            "no emphasis, reach 8": 1190.55,
            "no emphasis, one size, reach 3": 1195.6,
        },
    },
    "heldout_loglik_other_models": {
        "study-task1": {"under": 366.6, "scale-free": 375.12, "boltzmann": 378.34},
        "study-task2": {"under": 935.5, "scale-free": 863.65, "boltzmann": 859.96},
        "study-task3": {"under": 925.9, "scale-free": 872.38, "boltzmann": 864.94},
    },
    "source": "the authors' user study (github VT-Collab/StROL_RAL, data removed at d383bef): "
    "12 participants x 3 Tasks x 3 learners, imported with strol-bench import-study (one "
    "update per correction); every correction of a Task's 36 sessions",
    "command": "python lab/aim_variants.py LOGS (the variants' held-out table), then "
    "python lab/aim_variants.py LOGS --shipped 'no emphasis, one size, reach 3;all;no "
    "emphasis, reach 3' (the aimed family of fit-human, sandwich intervals with the "
    "leave-one-person-out covariance; held-out: 4 folds of people, seed 1); the other "
    "models: strol-bench fit-human (docs/humans.md, 'Fitted to the twelve people')",
    "date": "2026-11-29",
}
"""The fit behind ``fitted-aimed`` (docs/humans.md, "The aimed person"): per study Task the
maximum-likelihood values, their 95 % intervals over people and the held-out log-likelihood
(4 folds of people) of the variant chosen among those tried (``fixed``: held, not fitted): the
steepest ascent of θ* ⊙ w with a fitted per-feature emphasis w, or, with no emphasis, the best
direction for a push of ``reach`` 3 a_max (30 cm). Task 1: the reach, one size (424.4 against
423.6); Task 2: the emphasis (1248.3 against 1233.0 at reach 3); Task 3: the reach (1218.5
against 1172.0). Reach 3 was taken for every Task before the grid 1.3-8 (each Task's best of it
gains at most 17 more, chosen on the same folds, so not taken). Against per-axis noise on the
same corrections: ``under`` 366.6 / 935.5 / 925.9, ``scale-free`` 375.1 / 863.6 / 872.4.
``params``: elsewhere, Task 3's values (no emphasis: any Task's features)."""


class AimedModel(HumanModel):
    """A push about θ*'s steepest ascent with its aim error in the direction, the rotation
    weighed by ρ, and a log-normal size or two (module docstring). Ignores θ̂. Parameters: σ, ε
    (default 0), ``aim`` = τ (≥ 0), ``turn`` = ρ (> 0), ``size`` (median length, units of
    a_max), ``size_sd`` (its log sd), ``small_share`` (probability of the second size),
    ``small_size`` (its median), ``emphasis`` (one weight ≥ 0 per feature, default all 1: the
    person aims for θ* ⊙ w), ``reach`` (the push length, units of a_max, whose best direction
    it aims at: :func:`aim_direction`; 0, the default, the steepest ascent), ``n_candidates``
    (kept for the interface: no candidates)."""

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        aim: float = 1.0,
        turn: float = 1.0,
        size: float = 1.2,
        size_sd: float = 0.5,
        small_share: float = 0.0,
        small_size: float = 0.3,
        emphasis: Sequence[float] | None = None,
        reach: float = 0.0,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.emphasis = check_emphasis(task, emphasis)
        self.reach = check_fraction("reach", reach)
        if self.reach > MAX_SIZE:
            raise ValueError(f"reach must be a number in [0, {MAX_SIZE:g}], got {reach!r}")
        self.aim = check_fraction("aim", aim)
        if self.aim > MAX_AIM:
            raise ValueError(f"aim must be a number in [0, {MAX_AIM:g}], got {aim!r}")
        self.size_sd = check_fraction("size_sd", size_sd)
        self.small_share = check_probability("small_share", small_share)
        for name, given, high in (
            ("turn", turn, MAX_TURN),
            ("size", size, MAX_SIZE),
            ("small_size", small_size, MAX_SIZE),
        ):
            value = check_fraction(name, given)
            if not 0.0 < value <= high:
                raise ValueError(f"{name} must be a number in (0, {high:g}], got {given!r}")
            setattr(self, name, value)

    def params(self) -> dict[str, float]:
        """The model's own parameters (:data:`AIM_PARAMS`) by name."""
        return {k: getattr(self, k) for k in AIM_PARAMS}

    def draw(self, rng: np.random.Generator, n: int) -> Draws:
        """No candidates (an empty (n, 0, a) block): the direction's and the size's draws only,
        then the shared noise."""
        a = self.task.action_dim
        extra = self.draw_extra(rng, n)
        return Draws(np.zeros((n, 0, a)), rng.standard_normal((n, a)), extra)

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        a = self.task.action_dim
        return {"z": rng.standard_normal((n, a + 1)), "pick": rng.random(n)}

    def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        best = aim_direction(self.task, x, u_r, theta_star * self.emphasis, self.reach)
        u = aimed_corrections(best, draws.extra["z"], draws.extra["pick"], **self.params())
        return u * np.asarray(self.task.action_bound, dtype=np.float64)


AIM_PARAMS = ("aim", "turn", "size", "size_sd", "small_share", "small_size")
"""The model's own scalar parameters, in the order of :class:`AimedModel`'s signature (then
``emphasis``, one per feature)."""
MAX_EMPHASIS = 1e3
"""The largest feature weight accepted."""


def check_emphasis(task: Task, emphasis: Sequence[float] | None) -> np.ndarray:
    """``emphasis`` as d weights in [0, MAX_EMPHASIS], not all 0 (None: all 1); else ValueError
    naming it."""
    if emphasis is None:
        return np.ones(task.dim)
    w = checks.vector("emphasis", emphasis, task.dim)
    if not (np.all(w >= 0.0) and np.all(w <= MAX_EMPHASIS) and np.any(w > 0.0)):
        raise ValueError(
            f"emphasis must be {task.dim} weights in [0, {MAX_EMPHASIS:g}], not all 0 (one per "
            f"feature: {', '.join(task.feature_names)}), got {list(emphasis)!r}"
        )
    return w


def emphasis_names(task: Task) -> tuple[str, ...]:
    """The fitted names of the emphasis weights: ``w_<feature>`` for every feature after the
    first (the first is 1: only the weights' ratios change the direction)."""
    return tuple(f"w_{name}" for name in task.feature_names[1:])


def emphasis_of(task: Task, values: dict[str, float]) -> np.ndarray:
    """The emphasis vector (d,) from fitted ``w_<feature>`` values (1 for the first feature and
    any not given)."""
    return np.array([1.0] + [float(values.get(k, 1.0)) for k in emphasis_names(task)])


def fitted_aim_params(task: Task) -> dict[str, Any]:
    """:data:`FITTED_AIM`'s values for ``task`` as :class:`AimedModel`'s keyword arguments: its
    study Task's (``study-taskN``), else Task 3's (no emphasis: any Task's features)."""
    number = getattr(task, "number", None)
    per = FITTED_AIM["per_task"].get(study_task_name(0, number)) if number is not None else None
    if per is None:
        mean = FITTED_AIM["params"]  # Task 3's
        return {**{k: float(mean[k]) for k in AIM_PARAMS}, "reach": float(mean["reach"])}
    values = per["estimate"]
    out: dict[str, Any] = {k: float(values[k]) for k in AIM_PARAMS}
    out["emphasis"] = emphasis_of(task, values)
    out["reach"] = float(values.get("reach", 0.0))
    return out


class FittedAimedModel(AimedModel):
    """The aimed person as fitted to the twelve people of the authors' study, Task by Task
    (:data:`FITTED_AIM`); outside the study Tasks, Task 3's. Parameters as
    ``aimed``; one given (not None) overrides the fit's."""

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        aim: float | None = None,
        turn: float | None = None,
        size: float | None = None,
        size_sd: float | None = None,
        small_share: float | None = None,
        small_size: float | None = None,
        emphasis: Sequence[float] | None = None,
        reach: float | None = None,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        given = (aim, turn, size, size_sd, small_share, small_size, emphasis, reach)
        names = (*AIM_PARAMS, "emphasis", "reach")
        mine = {k: v for k, v in zip(names, given, strict=True) if v is not None}
        values = {**fitted_aim_params(task), **mine}
        super().__init__(task, sigma, bias, n_candidates=n_candidates, **values)


__all__ = [
    "AIM_PARAMS",
    "FITTED_AIM",
    "AimedModel",
    "FittedAimedModel",
    "aim_direction",
    "aimed_corrections",
    "check_emphasis",
    "emphasis_names",
    "emphasis_of",
    "fitted_aim_params",
    "log_density",
    "log_direction_density",
    "push_gradient",
    "steepest_ascent",
]
