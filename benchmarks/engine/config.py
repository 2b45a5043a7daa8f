"""The resolved configuration of a benchmark: what every result in a folder depends on.

A :class:`BenchConfig` is a list of experiments (env × condition × run seeds), the learners and
the size of a unit of work. Its JSON form goes into ``meta.json``; its hash, into every record,
so a resumed run can prove it continues the same benchmark.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Sequence
from typing import Any

import strol_gym
import strol_gym.learners.registry  # noqa: F401
from strol_gym.benchmarks.engine.conditions import (
    PAPER_LEARNERS,
    PAPER_TABLE_LEARNERS,
    REFERENCE_LEARNER,
    Condition,
    env_preset,
    is_paper_condition,
)
from strol_gym.humans.spec import DEFAULT_PERSON
from strol_gym.registry import install_specs, user_specs

DEFAULT_BLOCK = 25
"""Run seeds per unit of work. Fixed by the config, never by --jobs, so that batched numerics see
the same batches whatever the parallelism (and results are identical across --jobs)."""

SCHEMA_VERSION = 1
MAX_RUNS = 1_000_000
"""The most runs per experiment (env × condition): the paper uses 100–250, and a run's record
is kept in memory while the tables are built, so far more than this cannot finish anyway."""
MAX_TOTAL_RUNS = 10_000_000
"""The most runs in one config, summed over its experiments (a meta.json listing 300
experiments × 10⁶ runs would plan 1.2·10⁷ units before anything ran)."""
MAX_EXPERIMENTS = 10_000
"""The most experiments in one config (the paper's tables have 8)."""


def env_class(env_id: str) -> Any:
    """The class (or creator) ``gymnasium.make(env_id)`` calls, its module imported first for a
    ``"module:Env-v0"`` id, as ``gymnasium.make`` does; None when it cannot be found."""
    import importlib

    import gymnasium as gym
    from gymnasium.envs.registration import load_env_creator

    module, _, name = env_id.rpartition(":")
    try:
        if module:
            importlib.import_module(module)
        entry = gym.spec(name).entry_point
        return load_env_creator(entry) if isinstance(entry, str) else entry
    except (ImportError, gym.error.Error, AttributeError):
        return None


@dataclasses.dataclass(frozen=True)
class Experiment:
    """One env × one condition: runs with seeds ``seed, seed + 1, …, seed + runs − 1``."""

    env: str
    condition: Condition
    runs: int
    seed: int = 0
    n_corrections: int | None = None
    task: str | None = None
    """A Task name or "module:attr" (``gymnasium.make(..., task=...)``); None: the env's own."""

    def __post_init__(self) -> None:
        env_preset(self.env)  # validates the key
        if self.task is not None and (not isinstance(self.task, str) or not self.task):
            raise ValueError(f"task must be a Task name or 'module:attr', got {self.task!r}")
        if not 1 <= int(self.runs) <= MAX_RUNS:
            raise ValueError(f"runs must be an integer in [1, {MAX_RUNS}], got {self.runs}")
        if int(self.seed) < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")
        if self.n_corrections is not None and int(self.n_corrections) < 1:
            raise ValueError(f"n_corrections must be >= 1, got {self.n_corrections}")

    @property
    def env_id(self) -> str:
        return env_preset(self.env).env_id

    @property
    def corrections(self) -> int:
        """Correction steps per episode (the env's preset unless overridden)."""
        if self.n_corrections is None:
            return env_preset(self.env).n_corrections
        return int(self.n_corrections)

    @property
    def seeds(self) -> range:
        return range(int(self.seed), int(self.seed) + int(self.runs))

    def env_kwargs(self) -> dict[str, Any]:
        """gymnasium.make kwargs: the condition plus exactly ``corrections`` steps per episode."""
        preset = env_preset(self.env)
        kw = {
            **self.condition.env_kwargs(),
            **(preset.make_kwargs or {}),
            "max_episode_steps": self.corrections,
        }
        if preset.corrections_kwarg:
            kw["n_corrections"] = self.corrections
        if self.task is not None:
            kw["task"] = self.task
        return kw

    def person_as_used(self) -> dict[str, Any] | None:
        """The person the env uses here (``HumanSpec.to_dict``; None: no simulated person),
        resolved by the env's class without building the env (``resolve_person``): ValueError
        naming a value the person does not use. ``{}`` for an env that is no strol-gym env.
        It imports what the experiment names: for the command's own config, never for one read
        from a file (``BenchConfig.persons``)."""
        cls = env_class(self.env_id)
        resolve = getattr(cls, "resolve_person", None)
        if resolve is None:
            return {}
        spec = resolve(self.env_kwargs().get("person", DEFAULT_PERSON))
        return None if spec is None else spec.to_dict()

    def is_paper(self) -> bool:
        """The paper's setting: its condition, the env's own Task and correction count."""
        return (
            self.task is None
            and self.corrections == env_preset(self.env).n_corrections
            and is_paper_condition(self.env, self.condition)
        )

    def to_dict(self) -> dict[str, Any]:
        d = {
            "env": self.env,
            "env_id": self.env_id,
            "condition": self.condition.to_dict(),
            "runs": int(self.runs),
            "seed": int(self.seed),
            "n_corrections": self.corrections,
        }
        if self.task is not None:
            d["task"] = self.task
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Experiment:
        return cls(
            env=d["env"],
            condition=Condition(**d["condition"]),
            runs=d["runs"],
            seed=d["seed"],
            n_corrections=d["n_corrections"],
            task=d.get("task"),
        )


@dataclasses.dataclass(frozen=True)
class Unit:
    """A unit of work: one block of run seeds of one experiment, every learner."""

    experiment: int
    seeds: tuple[int, ...]

    @property
    def key(self) -> str:
        return f"{self.experiment:03d}-{self.seeds[0]:07d}"


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    """Everything results depend on (learner names, experiments, block size)."""

    experiments: tuple[Experiment, ...]
    learners: tuple[str, ...] = PAPER_LEARNERS
    reference: str = REFERENCE_LEARNER
    block: int = DEFAULT_BLOCK
    learner_kwargs: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)
    plugins: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)
    """User-registered pieces the run uses, as ``{kind: {name: "module:attr"}}``: what a worker
    process registers before it builds anything (``with_user_specs``)."""

    def __post_init__(self) -> None:
        if not self.experiments:
            raise ValueError("a benchmark needs at least one experiment")
        if len(self.experiments) > MAX_EXPERIMENTS:
            raise ValueError(
                f"a benchmark may hold at most {MAX_EXPERIMENTS} experiments, got "
                f"{len(self.experiments)}"
            )
        total = sum(int(e.runs) for e in self.experiments)
        if total > MAX_TOTAL_RUNS:
            raise ValueError(
                f"a benchmark may hold at most {MAX_TOTAL_RUNS} runs in all, got {total}"
            )
        if not self.learners:
            raise ValueError("learners must name at least one learner")
        if len(set(self.learners)) != len(self.learners):
            raise ValueError(f"learners must be distinct, got {list(self.learners)}")
        if self.reference not in self.learners:
            raise ValueError(
                f"reference learner {self.reference!r} must be one of the learners "
                f"{list(self.learners)}"
            )
        if int(self.block) < 1:
            raise ValueError(f"block must be >= 1, got {self.block}")
        unknown = sorted(set(self.learner_kwargs) - set(self.learners))
        if unknown:
            raise ValueError(f"learner_kwargs names learners not in the run: {unknown}")
        keys = [(e.env, e.condition.name) for e in self.experiments]
        if len(set(keys)) != len(keys):
            raise ValueError(f"each (env, condition) may appear once, got {keys}")

    def is_paper(self) -> bool:
        """The paper's comparison: its learners and reference, its settings (H1/H2 apply)."""
        return (
            set(self.learners) in (set(PAPER_LEARNERS), set(PAPER_TABLE_LEARNERS))
            and self.reference == REFERENCE_LEARNER
            and not self.learner_kwargs
            and all(e.is_paper() for e in self.experiments)
        )

    def with_user_specs(self) -> tuple[BenchConfig, list[str]]:
        """This config with ``plugins`` set to the user registrations it uses, and the names
        of those that cannot reach a worker process (lambdas, closures, interactive code)."""
        used = {
            "env": [e.env for e in self.experiments],
            "learner": self.learners,
            "human": [e.condition.human for e in self.experiments if e.condition.human],
            "task": [e.task for e in self.experiments if e.task],
        }
        specs, stuck = user_specs(used)
        return dataclasses.replace(self, plugins=specs), stuck

    def persons(self) -> dict[str, dict[str, Any] | None]:
        """The person each experiment's env uses, by ``env/condition`` (``person_as_used``):
        what a results folder records beside its config (meta.json ``persons``); ValueError
        naming a value a person does not use, before any work."""
        return {f"{e.env}/{e.condition.name}": e.person_as_used() for e in self.experiments}

    def kwargs_for(self, learner: str) -> dict[str, Any]:
        """Constructor keyword arguments for ``learner`` (beyond the task)."""
        return dict(self.learner_kwargs.get(learner, {}))

    def units(self) -> list[Unit]:
        """All units of work, in a fixed order (experiment, then seed)."""
        out = []
        for i, exp in enumerate(self.experiments):
            seeds = list(exp.seeds)
            for j in range(0, len(seeds), self.block):
                out.append(Unit(i, tuple(seeds[j : j + self.block])))
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA_VERSION,
            "experiments": [e.to_dict() for e in self.experiments],
            "learners": list(self.learners),
            "reference": self.reference,
            "block": int(self.block),
            "learner_kwargs": {k: dict(v) for k, v in sorted(self.learner_kwargs.items())},
            **({"plugins": self.plugins} if self.plugins else {}),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any], trusted: bool = True) -> BenchConfig:
        """The config of ``to_dict`` output. ``trusted``: its user pieces (``plugins``) are
        registered (a worker, sent its parent's config); False for a file read from disk,
        whose ``module:attr`` pieces are never registered (reading data imports nothing)."""
        if d.get("schema") != SCHEMA_VERSION:
            raise ValueError(
                f"unknown results schema {d.get('schema')!r}, expected {SCHEMA_VERSION}"
            )
        install_specs(d.get("plugins", {}), code=trusted)  # a worker learns the user's names
        return cls(
            experiments=tuple(Experiment.from_dict(e) for e in d["experiments"]),
            learners=tuple(d["learners"]),
            reference=d["reference"],
            block=d["block"],
            learner_kwargs=d.get("learner_kwargs", {}),
            plugins=d.get("plugins", {}),
        )

    def hash(self, extra: dict[str, Any] | None = None) -> str:
        """A short SHA-256 of the canonical JSON of the config (plus ``extra``, e.g. versions)."""
        blob = json.dumps({"config": self.to_dict(), "extra": extra or {}}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


def paper_config(
    envs: Sequence[str],
    *,
    runs: int | None = None,
    seed: int = 0,
    learners: Sequence[str] = PAPER_TABLE_LEARNERS,
    reference: str = REFERENCE_LEARNER,
    block: int = DEFAULT_BLOCK,
    human: str | None = None,
) -> BenchConfig:
    """The paper's comparison for ``envs``: four conditions each, the paper's run counts.
    ``human`` replaces the conditions' human (a labelled variant, no longer the paper's)."""
    exps = []
    for env in envs:
        preset = env_preset(env)
        n = preset.runs if runs is None else int(runs)
        for cond in preset.conditions().values():
            if human is not None:
                cond = dataclasses.replace(cond, human=human)
            exps.append(Experiment(env=env, condition=cond, runs=n, seed=seed))
    return BenchConfig(tuple(exps), tuple(learners), reference, block)


def diff_configs(a: dict[str, Any], b: dict[str, Any], prefix: str = "") -> list[str]:
    """Human-readable paths where two JSON configs differ (for mismatch errors)."""
    out: list[str] = []
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            p = f"{prefix}.{k}" if prefix else str(k)
            if k not in a or k not in b:
                out.append(f"{p}: {a.get(k, '<missing>')!r} vs {b.get(k, '<missing>')!r}")
            else:
                out += diff_configs(a[k], b[k], p)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            out += diff_configs(x, y, f"{prefix}[{i}]")
    elif a != b:
        out.append(f"{prefix}: {a!r} vs {b!r}")
    return out
