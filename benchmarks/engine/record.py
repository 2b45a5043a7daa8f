"""One run's record, defined once: what a worker writes (``episodes.run_block``), a results
folder stores (``results``) and the analysis, the report and the experiments read."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal, NotRequired, TypedDict, cast

RunField = Literal["error", "cos_error", "regret"]
RUN_FIELDS: tuple[RunField, ...] = ("error", "cos_error", "regret")
"""The metrics every run has, in runs.csv's column order (``strol_gym.metrics.RUN_METRICS``)."""

RegretInput = Literal["theta_hat", "theta_star", "x0"]
REGRET_INPUTS: tuple[RegretInput, ...] = ("theta_hat", "theta_star", "x0")
"""What a plan's regret is scored from, for a whole unit at once (``episodes.score_regret``)."""

REQUIRED_FIELDS = ("env", "condition", "learner", "seed", "steps", "terminated", "errors")
"""The fields a stored record must hold before its values are checked (``results``)."""


class RunRecord(TypedDict):
    """One learner's run on one seed of one (env, condition)."""

    env: str
    condition: str
    learner: str
    seed: int
    error: float
    """‖θ* − θ̂‖ after the last step."""
    cos_error: float
    regret: float
    """NaN until ``score_regret`` (and for a Task without a planner)."""
    errors: list[float]
    """The error after each step, the start included."""
    cos_errors: list[float]
    steps: int
    terminated: bool
    theta_star: list[float]
    theta_hat: list[float]
    x0: list[float]
    first_correction: list[float] | None
    # episode totals the env reports (strol_gym.metrics.info_metrics(); a user's registered
    # metric too), per-correction sums (episodes.CORRECTION_METRICS) and what an experiment
    # adds: present only where they apply
    correction_time: NotRequired[float]
    corrections: NotRequired[float]
    gave_up: NotRequired[float]
    correction_time_authors: NotRequired[float]
    regret_authors: NotRequired[float]
    kernels: NotRequired[str]
    """The worker's floating-point kernels (stored once per unit, not per record)."""


def value(record: RunRecord, key: str) -> Any:
    """A metric of ``record`` by name (a registered metric's name need not be a field above);
    None when the run does not have it."""
    return cast(Mapping[str, Any], record).get(key)
