"""What every analysis module reads: the :class:`Analysis` of a results folder (summary cells,
paired tests, curves, verdicts), how tables spell learners and metrics.

The metric names, labels and directions come from the one metrics table, ``strol_gym.metrics``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from strol_gym.benchmarks.engine.config import BenchConfig
from strol_gym.benchmarks.engine.record import RunRecord, value
from strol_gym.metrics import RUN_METRICS, label

METRICS: tuple[str, ...] = RUN_METRICS
"""The metrics of every run, in table order: regret, error, 1 − cos."""
METRIC_LABELS = {m: label(m) for m in METRICS}


def display(name: str) -> str:
    """How tables spell a learner (its registration's display name; else its name)."""
    from strol_gym.learners.registry import display_name

    return display_name(name)


@dataclasses.dataclass
class Analysis:
    """Everything the tables, plots and verdicts need."""

    config: BenchConfig
    summary: list[dict[str, Any]]
    posthoc: list[dict[str, Any]]
    anova: list[dict[str, Any]]
    curves: dict[tuple[str, str, str], dict[str, np.ndarray]]
    verdicts: list[dict[str, Any]]
    pooled: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    """Per env with several conditions: the whole-experiment test on its primary metric
    (``pooled_tests`` over the conditions; the paper's "across all trials and conditions")."""
    runs: dict[tuple[str, str, str], np.ndarray] = dataclasses.field(default_factory=dict)
    """(env, condition, metric) -> the (runs, learners) matrix the tests used (paired rows in
    seed order, learners in the config's order): what the figures show run by run."""
    aggregates: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    """Per env × metric with several conditions: IQM and P(improvement) over all of them,
    bootstrapped within each condition (``report.aggregate``)."""
    resamples: int = 0
    """Bootstrap resamples behind the intervals (0: none computed)."""

    def cell(self, env: str, cond: str, learner: str, metric: str) -> dict[str, Any] | None:
        for r in self.summary:
            key = (r["env"], r["condition"], r["learner"], r["metric"])
            if key == (env, cond, learner, metric):
                return r
        return None

    def test(self, env: str, cond: str, baseline: str, metric: str) -> dict[str, Any] | None:
        for r in self.posthoc:
            key = (r["env"], r["condition"], r["baseline"], r["metric"])
            if key == (env, cond, baseline, metric):
                return r
        return None

    def metrics_for(self, env: str) -> list[str]:
        """The metrics with data for ``env`` (regret is NaN where a task has no planner)."""
        return [
            m for m in METRICS if any(r["env"] == env and r["metric"] == m for r in self.summary)
        ]


def _matrix(records: Sequence[RunRecord], env: str, cond: str, learners: Sequence[str], key: str):
    """(seeds, learners) array of ``key``; rows are run seeds in ascending order."""
    by = {
        (r["seed"], r["learner"]): value(r, key)
        for r in records
        if (r["env"], r["condition"]) == (env, cond)
    }
    seeds = sorted({s for s, _ in by})
    return seeds, np.array(
        [[_f(by[(s, learner)]) for learner in learners] for s in seeds], dtype=np.float64
    )


def _f(v: Any) -> float:
    return math.nan if v is None else float(v)
