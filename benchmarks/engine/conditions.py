"""The paper's evaluation conditions (Fig. 4 columns) and the per-env presets.

A :class:`Condition` is everything about the simulated human that the benchmark varies: noise σ
and bias ε (fractions of a_max, docs/benchmark.md), the prior θ* is drawn from, and the human model.
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
from strol_gym.humans.spec import DEFAULT_BETA, DEFAULT_HUMAN, HumanSpec, check_shared
from strol_gym.limits import check_size
from strol_gym.metrics import RUN_METRICS
from strol_gym.priors import PRIORS
from strol_gym.registry import Registry, call_piece

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
    """A simulated-human setting: σ, ε (fractions of a_max), prior, human model (and its β).

    ``human=None`` leaves the env's default human model (the eq. M6 teacher for the Robot);
    otherwise it names a human (``strol_gym.humans.HUMANS``) or is a ``"module:attr"``.
    ``beta`` reaches the human only if its factory declares it.
    """

    name: str
    sigma: float
    bias: float = 0.0
    prior: str = "bimodal"
    human: str | None = None
    beta: float | None = None
    human_kwargs: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise ValueError(f"condition name must be a non-empty string, got {self.name!r}")
        beta = DEFAULT_BETA if self.beta is None else self.beta
        check_shared(self.sigma, self.bias, beta)  # the human's own checks, named as the env's
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

    def human_spec(self) -> HumanSpec:
        """The condition's human as the envs take it (the env's default model when unset);
        resolves the model, so a user's human must be registered by then."""
        return HumanSpec(
            self.human or DEFAULT_HUMAN,
            self.sigma,
            self.bias,
            DEFAULT_BETA if self.beta is None else self.beta,
            dict(self.human_kwargs or {}),
        )

    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for ``gymnasium.make`` (the env contract in docs/extending.md)."""
        kw: dict[str, Any] = {"sigma": self.sigma, "bias": self.bias, "prior": self.prior}
        if self.human is not None:
            kw["human"] = self.human
        if self.beta is not None:
            kw["beta"] = self.beta
        if self.human_kwargs:
            kw["human_kwargs"] = dict(self.human_kwargs)
        return kw

    def to_dict(self) -> dict[str, Any]:
        """JSON form; ``human_kwargs`` only when set (older results folders keep their hash)."""
        d = dataclasses.asdict(self)
        if d["human_kwargs"] is None:
            del d["human_kwargs"]
        return d

    def describe(self) -> str:
        """One line for tables: σ, ε, prior, human."""
        h = self.human or "env-default"
        h = h if self.beta is None else f"{h} (β={self.beta:g})"
        if self.human_kwargs:
            h += " " + ", ".join(f"{k}={v}" for k, v in sorted(self.human_kwargs.items()))
        return f"σ={self.sigma:g}, ε={self.bias:g}, {self.prior} prior, {h} human"


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
    training_sigma: float
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

    def __post_init__(self) -> None:
        if not isinstance(self.key, str) or not self.key or ":" in self.key:
            raise ValueError(f"key must be a non-empty string without ':', got {self.key!r}")
        if not isinstance(self.env_id, str) or not self.env_id:
            raise ValueError(f"env_id must be a gymnasium env id, got {self.env_id!r}")
        for name in ("runs", "n_corrections"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        if not (math.isfinite(self.training_sigma) and self.training_sigma >= 0):
            raise ValueError(
                f"training_sigma must be a finite number >= 0, got {self.training_sigma}"
            )
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
        """The paper's four conditions for this env (docs/benchmark.md's table), in figure order."""
        return {name: make_condition(self.key, name) for name in CONDITION_NAMES}


ENV_PRESETS: dict[str, EnvPreset] = {
    key: EnvPreset(key, env_id, runs, n_corrections, training_sigma, metric)
    for key, env_id, runs, n_corrections, training_sigma, metric in (
        # The paper's envs: run count, correction steps, training noise, primary metric.
        ("robot", "StROL-Robot-v0", 100, 5, 0.25, "regret"),
        ("highway", "StROL-Highway-v0", 250, 10, 0.10, "error"),
    )
}
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
    )
    # StROL-Study-v1 (u_H = the person's push): the held-out participant who judges what it
    # sees, and v0's regret-judging user with the training human's corrections ("oracle").
    for _who in ("observer", "oracle"):
        _key = f"study{_k}-v1" + ("" if _who == "observer" else "-oracle")
        ENV_PRESETS[_key] = dataclasses.replace(
            ENV_PRESETS[f"study{_k}"],
            key=_key,
            env_id="StROL-Study-v1",
            # v1's Tasks (their own ids, so learners find v1's ĝ), by registered name, so
            # logs and datasets name them without a module path.
            make_kwargs={"task": f"study-task{_k}-v1", "participant": _who},
        )
    # StROL-Study-v2: the fitted population (default), and v1's two for comparison.
    for _who in ("fitted", "observer", "oracle"):
        _key = f"study{_k}-v2" + ("" if _who == "fitted" else f"-{_who}")
        ENV_PRESETS[_key] = dataclasses.replace(
            ENV_PRESETS[f"study{_k}"],
            key=_key,
            env_id="StROL-Study-v2",
            make_kwargs={"task": f"study-task{_k}-v2", "participant": _who},
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
    bias: float = 0.0,
    prior: str = "bimodal",
    human: str | None = None,
    beta: float | None = None,
    human_kwargs: dict[str, Any] | None = None,
) -> Condition:
    """An explicit condition; σ defaults to the env's training noise. ``human`` must be a
    registered human or an importable "module:attr" (checked here)."""
    if human is not None:
        from strol_gym.humans import HUMANS

        HUMANS.check_name(human)
    preset = env_preset(env)
    return Condition(
        name=name,
        sigma=preset.training_sigma if sigma is None else float(sigma),
        bias=float(bias),
        prior=prior,
        human=human,
        beta=beta,
        human_kwargs=human_kwargs,
    )
