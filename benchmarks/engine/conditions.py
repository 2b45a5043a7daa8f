"""The paper's evaluation conditions (Fig. 4 columns) and the per-env presets.

A :class:`Condition` is everything about the simulated person that the benchmark varies: noise σ
and bias ε (fractions of a_max, docs/benchmark.md), the prior θ* is drawn from, and the person
(a human model, or an env's own person such as the study's "observer"). σ, ε, β and the
person's name are spellings of the env's one ``person=`` argument (``Condition.person``): a
value the person does not use is refused when the env resolves it.
The robot's initial estimate θ̂0 is *not* part of a condition: in every condition it is the mean
of the designer's bimodal prior modes (``task.prior_modes.mean(0)``), which is what the envs and
learners use by default. The uniform-prior condition changes only where θ* comes from.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

from strol_gym.benchmarks.engine.robots import ROBOTS
from strol_gym.envs.study.versions import VERSIONS
from strol_gym.humans.spec import DEFAULT_HUMAN, HumanSpec
from strol_gym.limits import check_size
from strol_gym.metrics import RUN_METRICS
from strol_gym.priors import PRIORS
from strol_gym.registry import Registry, call_piece
from strol_gym.tasks.study import study_task_name

PAPER_LEARNERS: tuple[str, ...] = ("gradient", "one", "mof", "e2e", "strol")
"""The paper's five rules, in the order its figures use (e2e with ‖ĝ‖ ≤ ‖g‖, as shipped for
every Task; the default of the other experiments)."""

PAPER_TABLE_LEARNERS: tuple[str, ...] = ("gradient", "one", "mof", "e2e", "e2e-scratch", "strol")
"""What ``strol-bench paper`` compares: the five rules plus ``e2e-scratch``, e2e as the paper
defines it (unbounded ĝ, "from scratch"; docs/fidelity.md), shipped for the Robot and Highway."""

REFERENCE_LEARNER = "strol"
"""The learner every post-hoc test compares against the others."""


@dataclasses.dataclass(frozen=True)
class Condition:
    """A simulated-person setting: σ, ε (fractions of a_max), prior, person (and its β).

    ``human=None`` leaves the env's default person (the eq. M6 teacher for the Robot, the
    fitted population for StROL-Study-v2); otherwise it names a human
    (``strol_gym.humans.HUMANS``), an env's own person or a ``"module:attr"``. σ, ε and β left
    None are not given (the person's default, or unused); a value given that the person does
    not use is refused when the env is made.
    """

    name: str
    sigma: float | None = None
    bias: float | None = None
    prior: str = "bimodal"
    human: str | None = None
    beta: float | None = None
    human_kwargs: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise ValueError(f"condition name must be a non-empty string, got {self.name!r}")
        # the ranges, by the one check the envs' person= uses (the name is resolved by the env)
        HumanSpec(DEFAULT_HUMAN, self.sigma, self.bias, self.beta)
        if not isinstance(self.prior, str) or (self.prior not in PRIORS and ":" not in self.prior):
            raise ValueError(
                f"prior must be one of {PRIORS.names()} (registered priors) or 'module:attr', "
                f"got {self.prior!r}"
            )
        if self.human is not None and (not isinstance(self.human, str) or not self.human):
            raise ValueError(
                f"human must be a registered human's name or 'module:attr', got {self.human!r}"
            )
        if self.human_kwargs is not None and not isinstance(self.human_kwargs, dict):
            raise ValueError(f"human_kwargs must be a dict, got {self.human_kwargs!r}")
        for key in ("n_candidates",):  # sizes: refused here, before a worker allocates them
            if self.human_kwargs and key in self.human_kwargs:
                check_size(f"human_kwargs[{key!r}]", self.human_kwargs[key], key)

    def person(self) -> dict[str, Any] | None:
        """The env's ``person=`` argument as a dict of ``HumanSpec`` fields (no ``name``: the
        env's default person), or None when the condition sets nothing (the env's default)."""
        d: dict[str, Any] = {} if self.human is None else {"name": self.human}
        d |= {k: v for k in ("sigma", "bias", "beta") if (v := getattr(self, k)) is not None}
        if self.human_kwargs:
            d["kwargs"] = dict(self.human_kwargs)
        return d or None

    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for ``gymnasium.make`` (the env contract in docs/extending.md)."""
        kw: dict[str, Any] = {"prior": self.prior}
        person = self.person()
        if person is not None:
            kw["person"] = person
        return kw

    def to_dict(self) -> dict[str, Any]:
        """JSON form; ``human_kwargs`` only when set."""
        d = dataclasses.asdict(self)
        if d["human_kwargs"] is None:
            del d["human_kwargs"]
        return d

    def describe(self) -> str:
        """One line for tables: σ, ε (those set), prior, person."""
        h = self.human or "env-default"
        h = h if self.beta is None else f"{h} (β={self.beta:g})"
        if self.human_kwargs:
            h += " " + ", ".join(f"{k}={v}" for k, v in sorted(self.human_kwargs.items()))
        shared = [f"{s}={v:g}" for s, v in (("σ", self.sigma), ("ε", self.bias)) if v is not None]
        return ", ".join([*shared, f"{self.prior} prior, {h} person"])


PRIMARY_METRICS = RUN_METRICS
"""What an env preset may rank by: the metrics every run has (``strol_gym.metrics``)."""


@dataclasses.dataclass(frozen=True)
class EnvPreset:
    """What the benchmark fixes per environment: id, run count, correction steps, the training
    condition's noise and the primary metric. ``env_id`` may be ``"module:Env-v0"`` (gymnasium
    then imports ``module`` first, which is how a worker process finds a user's env)."""

    key: str
    env_id: str
    runs: int
    n_corrections: int
    training_sigma: float | None
    """The training condition's σ (None: the env's person takes none, its noise is fitted)."""
    primary_metric: str
    make_kwargs: dict[str, Any] | None = None
    """Extra ``gymnasium.make`` kwargs (the study presets' ``task``)."""
    robot: str = "task"
    """How the runner's robot acts, a name in ``robots.ROBOTS``: "task" (``task.robot_policy``,
    scaled to the action space), "zeros" (the env drives its own robot and the action is a
    residual on it) or one added with ``register_robot``."""
    corrections_kwarg: bool = True
    """Whether the env takes ``n_corrections``; if not (the study env, whose user corrects when
    it chooses), ``n_corrections`` only sets the episode's length in steps."""
    paper_human: str | None = None
    """The human of the paper's four conditions (None: the env's default human). The Highway's
    is the driver, the paper's "model predictive controller" (l. 323), not the env's default
    eq. M6 teacher."""
    paper_conditions: bool = True
    """Whether the paper's four conditions (Fig. 4) apply to this env (``conditions``,
    ``strol-bench list``); the study's envs run the study's own condition."""

    def __post_init__(self) -> None:
        if not isinstance(self.key, str) or not self.key or ":" in self.key:
            raise ValueError(f"key must be a non-empty string without ':', got {self.key!r}")
        if not isinstance(self.env_id, str) or not self.env_id:
            raise ValueError(f"env_id must be a gymnasium env id, got {self.env_id!r}")
        for name in ("runs", "n_corrections"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        sigma = self.training_sigma
        if sigma is not None and not (math.isfinite(sigma) and sigma >= 0):
            raise ValueError(f"training_sigma must be None or a finite number >= 0, got {sigma}")
        if self.primary_metric not in PRIMARY_METRICS:
            raise ValueError(
                f"primary_metric must be one of {PRIMARY_METRICS}, got {self.primary_metric!r}"
            )
        if not isinstance(self.robot, str) or (self.robot not in ROBOTS and ":" not in self.robot):
            raise ValueError(
                f"robot must be one of {ROBOTS.names()} (registered robots) or 'module:attr', "
                f"got {self.robot!r}"
            )
        if self.make_kwargs is not None and not isinstance(self.make_kwargs, dict):
            raise ValueError(f"make_kwargs must be a dict or None, got {self.make_kwargs!r}")

    def conditions(self) -> dict[str, Condition]:
        """The paper's four conditions for this env (docs/benchmark.md's table), in figure
        order; none for an env they do not apply to (``paper_conditions``)."""
        if not self.paper_conditions:
            return {}
        return {name: make_condition(self.key, name) for name in CONDITION_NAMES}


ENV_PRESETS: dict[str, EnvPreset] = {
    key: EnvPreset(key, env_id, runs, n_corrections, training_sigma, metric)
    for key, env_id, runs, n_corrections, training_sigma, metric in (
        # The paper's envs: run count, correction steps, training noise, primary metric.
        ("robot", "StROL-Robot-v0", 100, 5, 0.25, "regret"),
        ("highway", "StROL-Highway-v0", 250, 10, 0.10, "error"),
    )
}
"""The paper's envs; the study's, below, run the study's own condition (``strol-bench study``),
not the paper's four (``paper_conditions``)."""
ENV_PRESETS["highway"] = dataclasses.replace(ENV_PRESETS["highway"], paper_human="driver")


PAPER_ENVS: tuple[str, ...] = tuple(ENV_PRESETS)
"""The paper's envs (``strol-bench paper``); ``register_env_preset`` adds more for ``run``."""

STUDY_EPISODE_STEPS = 1200
"""The study env's 60 s session in 0.05 s steps (docs/study.md)."""

for _k in (1, 2, 3):  # the user study's Tasks (``strol-bench study``), not part of ``paper``
    ENV_PRESETS[f"study{_k}"] = EnvPreset(
        key=f"study{_k}",
        env_id="StROL-Study-v0",
        runs=20,
        n_corrections=STUDY_EPISODE_STEPS,
        training_sigma=0.25,
        primary_metric="regret",
        make_kwargs={"task": _k},
        robot="zeros",
        corrections_kwarg=False,
        paper_conditions=False,
    )
    # The later versions (u_H = the person's push), one preset per Task: the version's default
    # person (v1's participant who judges what it sees; v2's fitted population, whose noise is
    # fitted: no training σ); its other people are a condition's person (``strol-bench study
    # --participant``). Their Tasks by registered name (their own ids, so learners find their
    # ĝ, and logs and datasets name them without a module path).
    for _v in VERSIONS.values():
        if _v.participants:
            ENV_PRESETS[f"study{_k}-{_v.name}"] = dataclasses.replace(
                ENV_PRESETS[f"study{_k}"],
                key=f"study{_k}-{_v.name}",
                env_id=_v.env_id,
                training_sigma=None if _v.participants[0] == "fitted" else 0.25,
                make_kwargs={"task": study_task_name(_v.number, _k)},
            )


def _check_preset(key: str, preset: object) -> None:
    if not isinstance(preset, EnvPreset) or preset.key != key:
        raise ValueError(f"env {key!r} must be an EnvPreset with key {key!r}, got {preset!r}")


ENVS = Registry[EnvPreset](
    "env",
    ENV_PRESETS,
    check=_check_preset,
    encode=dataclasses.asdict,
    decode=lambda d: EnvPreset(**d),
)


def register_env_preset(preset: EnvPreset) -> None:
    """Make an env available to ``strol-bench run --env KEY`` (and ``list``)."""
    if not isinstance(preset, EnvPreset):
        raise ValueError(f"preset must be an EnvPreset, got {preset!r}")
    ENVS.register(preset.key, preset)


def env_preset(key: str) -> EnvPreset:
    """The preset for ``key`` ("robot", "highway" or a registered one); ValueError listing them."""
    try:
        return ENV_PRESETS[key]
    except (KeyError, TypeError):
        raise ValueError(f"env must be one of {sorted(ENV_PRESETS)}, got {key!r}") from None


# ---------------------------------------------------------------------- the conditions' registry
ConditionFactory = Callable[[EnvPreset], Condition]


def _training(p: EnvPreset) -> Condition:
    return Condition(
        "training", sigma=p.training_sigma, bias=0.0, prior="bimodal", human=p.paper_human
    )


def _clean(p: EnvPreset) -> Condition:
    return Condition("clean", sigma=0.0, bias=0.0, prior="bimodal", human=p.paper_human)


def _noisy_biased(p: EnvPreset) -> Condition:
    return Condition("noisy-biased", sigma=0.5, bias=0.5, prior="bimodal", human=p.paper_human)


def _uniform_prior(p: EnvPreset) -> Condition:
    return Condition(
        "uniform-prior", sigma=p.training_sigma, bias=0.0, prior="uniform", human=p.paper_human
    )


_CONDITIONS: dict[str, Condition | ConditionFactory | str] = {
    "training": _training,
    "clean": _clean,
    "noisy-biased": _noisy_biased,
    "uniform-prior": _uniform_prior,
}
CONDITION_NAMES: tuple[str, ...] = tuple(_CONDITIONS)
"""The paper's conditions (its Fig. 4 columns), in figure order."""


def _check_condition(name: str, cond: object) -> None:
    if not isinstance(cond, Condition) and not callable(cond):
        raise ValueError(
            f"condition {name!r} must be a Condition or a factory (EnvPreset) -> Condition, "
            f"got {cond!r}"
        )


CONDITIONS = Registry[Condition | ConditionFactory](
    "condition",
    _CONDITIONS,
    check=_check_condition,
    hint=" naming a Condition or a factory (EnvPreset) -> Condition",
)


def register_condition(name: str, condition: Condition | ConditionFactory | str) -> None:
    """Make ``condition`` (a Condition, a factory ``(EnvPreset) -> Condition`` or its
    "module:attr") available as ``strol-bench run --condition name``."""
    CONDITIONS.register(name, condition)


def make_condition(env: str, spec: str) -> Condition:
    """The condition named ``spec`` (registered or "module:attr") for ``env``."""
    preset = env_preset(env)
    obj = CONDITIONS.get(spec)
    cond = obj if isinstance(obj, Condition) else call_piece("condition", spec, obj, preset)
    if not isinstance(cond, Condition):
        raise ValueError(f"condition {spec!r} gave {type(cond).__name__}, not a Condition")
    if cond.name in CONDITION_NAMES and spec != cond.name:
        raise ValueError(f"condition {spec!r} must not reuse the paper's name {cond.name!r}")
    return cond


def paper_condition(env: str, name: str) -> Condition:
    """One of the paper's conditions for ``env``; ValueError listing the valid names."""
    if name not in CONDITION_NAMES:
        raise ValueError(f"condition must be one of {list(CONDITION_NAMES)}, got {name!r}")
    return make_condition(env, name)


def is_paper_condition(env: str, cond: Condition) -> bool:
    """Whether ``cond`` is exactly the paper's condition of that name for ``env``."""
    return cond.name in CONDITION_NAMES and cond == paper_condition(env, cond.name)


def custom_condition(
    env: str,
    *,
    name: str = "custom",
    sigma: float | None = None,
    bias: float | None = None,
    prior: str = "bimodal",
    human: str | None = None,
    beta: float | None = None,
    human_kwargs: dict[str, Any] | None = None,
) -> Condition:
    """An explicit condition; σ defaults to the env's training noise (none where the env's
    person takes none). ``human`` names the person (checked when the env is made: a
    registered human, an env's own person or an importable "module:attr")."""
    preset = env_preset(env)
    if sigma is None:
        sigma = preset.training_sigma
    return Condition(
        name=name,
        sigma=None if sigma is None else float(sigma),
        bias=None if bias is None else float(bias),
        prior=prior,
        human=human,
        beta=beta,
        human_kwargs=human_kwargs,
    )
