"""Statistics for heavy-tailed per-run scores: IQM, probability of improvement, performance
profiles, each with stratified bootstrap intervals over paired run seeds.

Robot regret is almost binary per run (most runs near 0, a few beyond a planner's regime switch
at 1–5), so a mean rests on a few runs and a mean ± SEM bar hides them. These estimators, after
Agarwal et al. (2021, "Deep RL at the edge of the statistical precipice"), describe the typical
run instead:

- **IQM**, the interquartile mean: the mean of the middle 50 % of the runs
  (``scipy.stats.trim_mean(x, 0.25)``: ⌊n/4⌋ runs cut from each end). Robust to the tails like
  the median, but uses half the runs rather than one or two.
- **Probability of improvement** P(reference better than baseline in a run): over paired runs
  (every learner of a run sees the same θ*, start and noise), the fraction of runs in which the
  reference's score is better, ties counting ½. 0.5 means neither is better in the typical run.
- **Performance profiles**: the fraction of runs with a score ≤ τ, for every τ (an empirical CDF
  per learner; higher is better for a lower-is-better score).

Intervals are percentile bootstrap intervals over run seeds. A resample draws whole rows of the
(runs × learners) matrix, so pairing survives; with strata (e.g. the conditions of a pooled
analysis) each stratum is resampled within itself, as rliable's stratified bootstrap does per
task. Every resample comes from a seeded generator: the same inputs give the same bytes.
"""

from __future__ import annotations

import dataclasses
import os
import zlib
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from strol_gym.lazy import LazyModule

if TYPE_CHECKING:
    from scipy import stats as sps
else:  # scipy loads on first use: `strol-bench --help` does not need it
    sps = LazyModule("scipy.stats")

BOOTSTRAP_RESAMPLES = 2000
"""Resamples for the benchmark's intervals (the Monte Carlo error of a 95 % percentile bound is
then about 0.005 in coverage); tests use 200 or fewer (``default_resamples``)."""
RESAMPLES_VAR = "STROL_BOOTSTRAP_RESAMPLES"
"""Environment variable that overrides ``BOOTSTRAP_RESAMPLES`` for the reports (the test suite
sets 200, so its benchmark runs stay fast; summary.md states the count it used)."""
MAX_RESAMPLES = 1_000_000
CHUNK_VALUES = 2_000_000
"""Resampled values held at once (16 MB of float64): the resamples are reduced in chunks."""
BOOTSTRAP_SEED = 3434
"""The root seed of every report's bootstrap; each cell mixes in its own key (``cell_rng``)."""
LEVEL = 0.95


@dataclasses.dataclass(frozen=True)
class Interval:
    """A point estimate per learner with its bootstrap interval (arrays of one length)."""

    estimate: np.ndarray
    low: np.ndarray
    high: np.ndarray


def default_resamples() -> int:
    """``BOOTSTRAP_RESAMPLES``, or the positive integer in ``$STROL_BOOTSTRAP_RESAMPLES``."""
    raw = os.environ.get(RESAMPLES_VAR, "").strip()
    if not raw:
        return BOOTSTRAP_RESAMPLES
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if not 1 <= n <= MAX_RESAMPLES:
        raise ValueError(f"{RESAMPLES_VAR} must be an integer in [1, {MAX_RESAMPLES}], got {raw!r}")
    return n


def cell_rng(*key: object) -> np.random.Generator:
    """A generator for one table cell, seeded by ``BOOTSTRAP_SEED`` and the cell's key (e.g. env,
    condition, metric): a cell's interval depends on its own data only, not on which other
    cells a report holds or in what order it computes them."""
    digest = zlib.crc32("/".join(map(str, key)).encode())
    return np.random.default_rng([BOOTSTRAP_SEED, digest])


def iqm(x: np.ndarray, axis: int | None = 0) -> np.ndarray | float:
    """Interquartile mean along ``axis``: the mean after cutting ⌊n/4⌋ values from each end."""
    x = np.asarray(x, dtype=np.float64)
    if x.size == 0:
        raise ValueError("iqm: x must hold at least one value")
    return sps.trim_mean(x, 0.25, axis=axis)


def bootstrap_indices(
    n: int,
    resamples: int,
    rng: np.random.Generator,
    strata: Sequence[object] | np.ndarray | None = None,
) -> np.ndarray:
    """(resamples, n) row indices drawn with replacement, within each stratum when ``strata``
    (one label per row) is given: a resample keeps every stratum's size."""
    if n < 1:
        raise ValueError(f"n must be ≥ 1, got {n}")
    if resamples < 1:
        raise ValueError(f"resamples must be ≥ 1, got {resamples}")
    if strata is None:
        return rng.integers(0, n, size=(resamples, n))
    labels = np.asarray(strata)
    if labels.shape != (n,):
        raise ValueError(f"strata must hold one label per row ({n}), got shape {labels.shape}")
    idx = np.empty((resamples, n), dtype=np.int64)
    for label in dict.fromkeys(labels.tolist()):
        rows = np.flatnonzero(labels == label)
        idx[:, rows] = rows[rng.integers(0, len(rows), size=(resamples, len(rows)))]
    return idx


def _percentiles(boot: np.ndarray, level: float) -> tuple[np.ndarray, np.ndarray]:
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level}")
    tail = 50.0 * (1.0 - level)
    low, high = np.percentile(boot, [tail, 100.0 - tail], axis=0)
    return low, high


def _matrix(y: np.ndarray) -> np.ndarray:
    y = np.asarray(y, dtype=np.float64)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[0] == 0:
        raise ValueError(f"y must have shape (runs ≥ 1, learners), got {np.shape(y)}")
    if not np.isfinite(y).all():
        raise ValueError("y must be finite (drop incomplete runs first: paired statistics)")
    return y


def iqm_interval(
    y: np.ndarray,
    *,
    rng: np.random.Generator,
    resamples: int = BOOTSTRAP_RESAMPLES,
    strata: Sequence[object] | np.ndarray | None = None,
    level: float = LEVEL,
) -> Interval:
    """IQM of each column of ``y`` (runs × learners) with its percentile bootstrap interval;
    rows are resampled together, so every learner sees the same resampled runs."""
    y = _matrix(y)
    idx = bootstrap_indices(len(y), resamples, rng, strata)
    boot = _chunked(idx, y, lambda block: sps.trim_mean(block, 0.25, axis=1))
    low, high = _percentiles(boot, level)
    return Interval(np.atleast_1d(iqm(y, axis=0)), low, high)


def _chunked(idx: np.ndarray, y: np.ndarray, reduce) -> np.ndarray:
    """``reduce(y[idx])`` (resamples × learners) computed a block of resamples at a time, so
    a large run count never holds every resampled matrix at once."""
    step = max(1, CHUNK_VALUES // max(1, idx.shape[1] * y.shape[1]))
    return np.concatenate([reduce(y[idx[i : i + step]]) for i in range(0, len(idx), step)])


def improvement(
    ref: np.ndarray, base: np.ndarray, *, tol: float = 0.0, lower_is_better: bool = True
) -> np.ndarray:
    """Per run: 1 where ``ref`` beats ``base``, ½ where they tie (|difference| ≤ ``tol``),
    else 0."""
    if tol < 0:
        raise ValueError(f"tol must be ≥ 0, got {tol}")
    d = np.asarray(ref, dtype=np.float64) - np.asarray(base, dtype=np.float64)
    if not lower_is_better:
        d = -d
    tie = np.abs(d) <= tol
    return np.where(tie, 0.5, (d < 0).astype(np.float64))


def probability_of_improvement(
    ref: np.ndarray, base: np.ndarray, *, tol: float = 0.0, lower_is_better: bool = True
) -> float:
    """P(``ref`` better than ``base`` in a paired run), ties counting ½."""
    w = improvement(ref, base, tol=tol, lower_is_better=lower_is_better)
    if w.size == 0:
        raise ValueError("probability_of_improvement: ref and base must hold at least one run")
    return float(w.mean())


def poi_interval(
    y: np.ndarray,
    reference: int,
    *,
    rng: np.random.Generator,
    resamples: int = BOOTSTRAP_RESAMPLES,
    strata: Sequence[object] | np.ndarray | None = None,
    tol: float = 0.0,
    lower_is_better: bool = True,
    level: float = LEVEL,
) -> Interval:
    """P(column ``reference`` better than each column of ``y`` in a run), ties ½, with its
    percentile bootstrap interval over runs (the reference's own column reads 0.5)."""
    y = _matrix(y)
    if not 0 <= reference < y.shape[1]:
        raise ValueError(f"reference must be a column of y (0–{y.shape[1] - 1}), got {reference}")
    w = improvement(y[:, [reference]], y, tol=tol, lower_is_better=lower_is_better)
    idx = bootstrap_indices(len(y), resamples, rng, strata)
    low, high = _percentiles(_chunked(idx, w, lambda block: block.mean(axis=1)), level)
    return Interval(w.mean(axis=0), low, high)


def performance_profile(scores: np.ndarray, taus: np.ndarray) -> np.ndarray:
    """Fraction of runs with a score ≤ τ, per column of ``scores`` (runs × learners) and per τ:
    shape (learners, len(taus)). NaN scores are left out of their column."""
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim == 1:
        s = s[:, None]
    t = np.asarray(taus, dtype=np.float64)
    if s.ndim != 2 or t.ndim != 1:
        raise ValueError("scores must be (runs, learners) and taus one-dimensional")
    out = np.full((s.shape[1], len(t)), np.nan)
    for j in range(s.shape[1]):
        col = np.sort(s[np.isfinite(s[:, j]), j])
        if len(col):
            out[j] = np.searchsorted(col, t, side="right") / len(col)
    return out


def profile_taus(scores: np.ndarray, num: int = 200, *, log: bool = False) -> np.ndarray:
    """A τ grid that spans the finite scores: linear from the smallest to the largest, or (with
    ``log``, for scores with a heavy right tail) 0 then log-spaced over the positive ones."""
    s = np.asarray(scores, dtype=np.float64)
    s = s[np.isfinite(s)]
    if s.size == 0:
        raise ValueError("profile_taus: scores hold no finite value")
    if num < 2:
        raise ValueError(f"num must be ≥ 2, got {num}")
    lo, hi = float(s.min()), float(s.max())
    pos = s[s > 0]
    if log and pos.size:
        low = max(float(pos.min()), float(pos.max()) * 1e-6)
        grid = np.geomspace(low, float(pos.max()), num - 1)
        return np.concatenate([[min(lo, 0.0)], grid])
    return np.linspace(lo, hi if hi > lo else lo + 1.0, num)
