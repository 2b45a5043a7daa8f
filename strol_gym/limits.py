"""The caps on sizes: one table, checked wherever a size enters, before anything is allocated.

Why fixed caps: a size that is only bounded by the machine's memory fails after minutes (or
takes the machine down); a typo (``n_particles=1e9``) should fail at once with a message naming
the argument and its cap. Every cap lies well above every shipped configuration and benchmark
(N = 1,024 sub-envs × 513 candidate actions included). ``docs/benchmark.md`` lists them
("Limits, failures and interrupts").

Lift them from Python with ``with strol_gym.limits.lifted(): ...`` (or ``lift(True)``), and from
the command line with ``--allow-large``; memory is then yours to watch.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

from strol_gym import checks

__all__ = ["CAPS", "check_size", "lift", "lifted", "lifted_now"]

CAPS: dict[str, int] = {
    "n_candidates": 8_192,  # candidate actions per state (shipped: 64-512)
    "n_particles": 200_000,  # bayes posterior particles (default 2,000)
    "n_hypotheses": 100_000,  # MOF's hypotheses (default: a few hundred)
    "num_envs": 16_384,  # sub-envs of a native vector env (benchmarks: 1,024)
    "block": 1_024,  # run seeds per unit of work (default 25); ~3.5 GB with two Robot learners
    "jobs": 1_024,  # worker processes (and never more than 4 per CPU: args.JOBS_PER_CPU)
    "threads": 1_024,  # torch threads of `train`
    "corrections": 10_000,  # correction steps per episode (`run`, `export`; paper: 5 and 10)
    "lambdas": 1_000,  # values in a --lambdas list
    "sigmas": 100,  # values in `robustness --sigmas` (default: 2), each a condition per human
    "session_line_bytes": 2**20,  # one session-log line (a correction is ~1 KB)
    "dataset_steps": 10_000_000,  # steps in one Minari dataset array (rows)
    "dataset_episodes": 1_000_000,  # episodes in one Minari dataset
    "fit_corrections": 5_000,  # corrections `fit-human` reads (~0.4 MB each; the study: ~600)
    "dataset_bytes": 2**30,  # bytes all arrays of one Minari dataset declare (ours: kilobytes)
}
"""Name -> the largest accepted value."""

ENV_VAR = "STROL_GYM_ALLOW_LARGE"
"""Set to "1" by :func:`lift` so that worker processes (spawned, Ray, Slurm) inherit it."""


_LIFTED = [os.environ.get(ENV_VAR) == "1"]


def lift(on: bool = True) -> None:
    """Lift (or restore) every cap for this process and the processes it starts."""
    _LIFTED[0] = bool(on)
    if on:
        os.environ[ENV_VAR] = "1"
    else:
        os.environ.pop(ENV_VAR, None)


def lifted_now() -> bool:
    """Whether the caps are lifted."""
    return _LIFTED[0]


@contextlib.contextmanager
def lifted() -> Iterator[None]:
    """The caps lifted inside a with-block."""
    before = _LIFTED[0]
    lift(True)
    try:
        yield
    finally:
        lift(before)


def check_size(name: str, value: object, cap: str | None = None, low: int = 1) -> int:
    """``value`` as an int in [low, CAPS[cap]] (cap defaults to ``name``), else ValueError (a
    number out of range) or ``checks.ArgumentTypeError`` (not a number: a TypeError that is
    also a ValueError) naming ``name`` and the valid range."""
    key = cap or name.lstrip("-").replace("-", "_")
    top = CAPS[key]
    valid = f"an integer in [{low}, {top:,}] (a fixed cap; --allow-large or limits.lift() lifts it)"
    if isinstance(value, bool) or (
        not hasattr(value, "__index__") and not isinstance(value, float)
    ):
        raise checks.ArgumentTypeError(f"{name} must be {valid}, got {value!r}")
    try:
        as_int = int(value)
    except (OverflowError, ValueError):  # inf, nan
        raise ValueError(f"{name} must be {valid}, got {value!r}") from None
    if as_int != value or as_int < low or (as_int > top and not _LIFTED[0]):
        raise ValueError(f"{name} must be {valid}, got {value!r}")
    return as_int
