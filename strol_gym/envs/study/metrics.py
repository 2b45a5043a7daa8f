"""The user study's metrics computed the authors' way, to set beside ours (labelled as such).

The paper's correction time and regret are not our seconds-above-15 N and eq. S1; its released
analysis computes them differently, so the published 1.4–2.5 s and 1.03–4.90 are different
quantities from ours. To compare like with like, this module recomputes them from our runs:

- **Correction time (authors' way)**: the wrench trace of each correction is resampled at
  20 Hz (zero-order hold, the latest reading at each 0.05 s tick, as a 20 Hz loop sees it);
  within the correction a tick counts only when the force magnitude ‖F‖ exceeds the running
  maximum of that correction so far (starting at 0, so the first tick counts); the time is
  0.05 s × the count, summed over the episode's finished corrections.
- **Regret (authors' way)**: R'(ξ*) − R'(ξ_θ̂) + 1.1, where R'(ξ) sums θ*·φ over the plan's
  waypoints for features 1–2 (pitcher, plate) but takes features 3–4 (table height, upright)
  at the last waypoint only, and 1.1 is the constant the authors' analysis adds. Both plans are
  ours (the Task's planner from the run's start), as in our regret.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from strol_gym.tasks.base import unique_rows

AUTHORS_DT = 0.05
"""The authors' control loop period (20 Hz): one logged sample is worth 0.05 s."""
REGRET_OFFSET = 1.1
"""The constant the authors' regret analysis adds to R(ξ*) − R(ξ_learned)."""
PATH_FEATURES = 2
"""Features 1..PATH_FEATURES (pitcher, plate) are summed over the waypoints; the rest (table
height, upright) are taken at the last waypoint only."""


def resample_hold(times: Any, values: Any, dt: float = AUTHORS_DT) -> np.ndarray:
    """``values`` (n, ...) sampled at ``times`` (n,), read at t0, t0 + dt, … ≤ t_end with a
    zero-order hold (the latest sample at or before each tick)."""
    t = np.asarray(times, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if t.ndim != 1 or len(t) != len(v):
        raise ValueError(f"times must be 1-D and match values' length, got {t.shape}, {v.shape}")
    if not dt > 0 or not math.isfinite(dt):
        raise ValueError(f"dt must be a positive finite number of seconds, got {dt}")
    if len(t) == 0:
        return v[:0]
    if np.any(np.diff(t) < 0):
        raise ValueError("times must be non-decreasing")
    n = math.floor((t[-1] - t[0]) / dt + 1e-9) + 1
    ticks = t[0] + dt * np.arange(n)
    idx = np.searchsorted(t, ticks + 1e-9, side="right") - 1
    return v[idx]


def new_maxima(force: Any) -> list[int]:
    """The indices of the samples that exceed the running maximum of the ones before them
    (from 0): where the authors' loop logged a pose during one correction."""
    peak, out = 0.0, []
    for i, f in enumerate(np.asarray(force, dtype=np.float64).reshape(-1).tolist()):
        if f > peak:
            peak = f
            out.append(i)
    return out


def record_samples(force: Any) -> int:
    """How many samples the authors' loop logs during one correction (``new_maxima``)."""
    return len(new_maxima(force))


def correction_samples(record: Mapping[str, Any], dt: float = AUTHORS_DT) -> int:
    """The authors' logged-sample count for one of the study env's correction records (its
    ``times`` and ``force`` (n, 3) trace): ‖F‖ resampled at 1/dt Hz, then ``record_samples``."""
    force = np.asarray(record["force"], dtype=np.float64).reshape(-1, 3)
    mags = np.sqrt(np.einsum("ij,ij->i", force, force))
    return record_samples(resample_hold(record["times"], mags, dt))


def correction_time(record: Mapping[str, Any]) -> float:
    """One correction's time the authors' way: 0.05 s × its logged samples."""
    return AUTHORS_DT * correction_samples(record)


def authors_return(task: Any, plans: np.ndarray, theta_star: np.ndarray) -> np.ndarray:
    """R'(ξ) for plans (B, T+1, s) under θ* (B, d): features 1–2 summed over waypoints 1..T,
    the others at waypoint T only."""
    phi = task.features(np.asarray(plans, dtype=np.float64)[:, 1:])  # (B, T, d)
    w = np.asarray(theta_star, dtype=np.float64)
    k = PATH_FEATURES
    path = np.einsum("btd,bd->b", phi[:, :, :k], w[:, :k])
    last = np.einsum("bd,bd->b", phi[:, -1, k:], w[:, k:])
    return path + last


def regret(task: Any, theta_hat: Any, theta_star: Any, x0: Any) -> np.ndarray:
    """The authors' regret, batched: R'(ξ*) − R'(ξ_θ̂) + 1.1, both planned from x0 -> (B,)."""
    theta_hat, theta_star, x0 = (
        np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (theta_hat, theta_star, x0)
    )
    theta, starts = np.concatenate([theta_star, theta_hat]), np.concatenate([x0, x0])
    first, inverse = unique_rows(theta, starts)  # θ*'s plan once per run seed
    plans = task.plan(theta[first], starts[first])[inverse]
    b = len(theta_star)
    star = authors_return(task, plans[:b], theta_star)
    learned = authors_return(task, plans[b:], theta_star)
    return star - learned + REGRET_OFFSET
