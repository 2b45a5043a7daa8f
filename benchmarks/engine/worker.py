"""One process's share of a benchmark: a cache of envs and wrapped learners, reused from unit
to unit, that runs a unit of work (a block of run seeds × every learner) into records."""

from __future__ import annotations

from typing import Any

from strol_gym.benchmarks.engine.conditions import env_preset
from strol_gym.benchmarks.engine.config import BenchConfig, Unit
from strol_gym.benchmarks.engine.episodes import run_block, score_regret
from strol_gym.benchmarks.engine.kernels import kernel_label
from strol_gym.benchmarks.engine.record import RunRecord
from strol_gym.benchmarks.engine.robots import robot_policy
from strol_gym.learners.registry import make_learner
from strol_gym.registry import install_specs


class Worker:
    """Per-process cache of envs and wrapped learners, so a unit does not rebuild them."""

    def __init__(self, config: BenchConfig) -> None:
        install_specs(config.plugins)  # the parent's user registrations, in a fresh process
        self.config = config
        self._exp: int | None = None
        self._envs: list[Any] = []
        self._wrapped: dict[str, list[Any]] = {learner: [] for learner in config.learners}

    def _prepare(self, exp_index: int, n: int) -> None:
        import gymnasium as gym

        import strol_gym  # noqa: F401
        from strol_gym.wrappers.online_learning import OnlineLearningWrapper, learning_env

        if self._exp != exp_index:
            self.close()
            self._exp = exp_index
        exp = self.config.experiments[exp_index]
        for name, wrapped in self._wrapped.items():
            while len(wrapped) < n:  # an env per learner and slot: the learners run in lockstep
                env = gym.make(exp.env_id, **exp.env_kwargs())
                self._envs.append(env)
                learner = make_learner(
                    name, task=learning_env(env).task, **self.config.kwargs_for(name)
                )
                wrapped.append(OnlineLearningWrapper(env, learner, regret=False))

    def close(self) -> None:
        for env in self._envs:
            env.close()
        self._envs, self._exp = [], None
        self._wrapped = {learner: [] for learner in self.config.learners}

    def run_unit(self, unit: Unit) -> list[RunRecord]:
        """Every learner on every seed of ``unit``: a list of per-run records (learner-major)."""
        exp = self.config.experiments[unit.experiment]
        n = len(unit.seeds)
        self._prepare(unit.experiment, n)
        task = self._envs[0].unwrapped.task
        policy = robot_policy(env_preset(exp.env).robot, task)
        runs = [
            (learner, seed, wrapped)
            for learner in self.config.learners
            for seed, wrapped in zip(unit.seeds, self._wrapped[learner][:n], strict=True)
        ]
        out = run_block(runs, exp.corrections, exp.env, exp.condition.name, policy)
        score_regret(task, out)
        label = kernel_label()  # this process's: a Ray worker's own CPU
        for r in out:
            r["kernels"] = label
        return out
