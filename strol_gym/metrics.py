"""The metrics of an episode: one table (name, label, direction) and one definition of each.

The wrapper reports them at the end of an episode, the benchmark runner records them per run
(scoring regret for a whole block at once), and the reports, the study, the confirmatory test
and the comparisons read their labels and directions from :data:`METRICS`. A user's env may
report more episode totals in its last ``info``; ``register_metric`` makes them known. A metric
has one name everywhere: the wrapper's ``info`` key, the record's field and the CSV column.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class Metric:
    """One metric: its record key, how tables and axes spell it, and its direction."""

    name: str
    label: str
    """Table headings: what it measures, in full."""
    short: str
    """Axis labels and table rows."""
    lower_is_better: bool = True
    from_info: bool = False
    """An episode total the env reports in its last ``info`` (the study env's correction time
    and count), copied into the record when present; otherwise computed from θ̂ and θ*."""


METRICS: dict[str, Metric] = {}
"""Every known metric by name, in the order tables list them."""


def register_metric(metric: Metric) -> Metric:
    """Add ``metric`` to :data:`METRICS` (a name already taken is an error)."""
    if not isinstance(metric, Metric):
        raise ValueError(f"metric must be a Metric, got {metric!r}")
    if metric.name in METRICS:
        raise ValueError(f"a metric named {metric.name!r} is already registered")
    METRICS[metric.name] = metric
    return metric


for _m in (
    Metric("regret", "Regret (eq. S1) of the plan for the final θ̂", "Regret"),
    Metric("error", "Error ‖θ* − θ̂‖₂ (raw, final)", "Error"),
    Metric("cos_error", "Scale-free error 1 − cos(θ*, θ̂) (final)", "1 − cos"),
    Metric("correction_time", "Correction time (s)", "Correction time (s)", from_info=True),
    Metric("corrections", "Corrections", "Corrections", from_info=True),
    Metric("gave_up", "Gave up (the participant stopped correcting)", "Gave up", from_info=True),
):
    register_metric(_m)

RUN_METRICS: tuple[str, ...] = tuple(n for n, m in METRICS.items() if not m.from_info)
"""The metrics every run has: ("regret", "error", "cos_error")."""


def info_metrics() -> tuple[str, ...]:
    """The episode totals an env may report in its last ``info`` (registered ones included)."""
    return tuple(n for n, m in METRICS.items() if m.from_info)


def metric(name: str) -> Metric:
    """The metric named ``name``; ValueError listing the known ones."""
    try:
        return METRICS[name]
    except KeyError:
        raise ValueError(f"unknown metric {name!r}; known metrics: {', '.join(METRICS)}") from None


def label(name: str) -> str:
    """A metric's full label (its name when it is not registered)."""
    return METRICS[name].label if name in METRICS else name


def short(name: str) -> str:
    """A metric's short label (its name when it is not registered)."""
    return METRICS[name].short if name in METRICS else name


# ---------------------------------------------------------------------- the definitions
def error(theta_star: np.ndarray, theta_hat: np.ndarray) -> float:
    """‖θ* − θ̂‖₂."""
    return float(np.linalg.norm(np.asarray(theta_star) - np.asarray(theta_hat)))


def cos_error(theta_star: np.ndarray, theta_hat: np.ndarray) -> float:
    """1 − cos(θ*, θ̂); 1.0 (no directional information) when either vector is zero."""
    ns, nh = np.linalg.norm(theta_star), np.linalg.norm(theta_hat)
    if ns == 0 or nh == 0:
        return 1.0
    return float(1.0 - np.dot(theta_star, theta_hat) / (ns * nh))


def episode_regret(task: Any, theta_hat: Any, theta_star: Any, x0: Any) -> list[float]:
    """``task.regret`` as floats, NaN for a task without a planner: (B, d), (B, d), (B, s) or
    single rows -> B floats. The one definition of the score both the wrapper and the benchmark
    runner (which batches a whole block of episodes) report."""
    try:
        return [float(r) for r in task.regret(theta_hat, theta_star, x0)]
    except NotImplementedError:
        return [float("nan")] * len(np.atleast_2d(theta_star))
