"""The paired benchmark runner: checks the learners, opens (or resumes) the results folder and
stores each unit of work as it finishes.

Design (docs/benchmark.md, paired runs): a run's seed fixes θ*, the start state and every
noise draw.
For every run seed, each learner gets ``env.reset(seed=run_seed)`` on an env built for the
condition, wrapped in ``OnlineLearningWrapper(env, learner)``; each step the robot acts by
``task.robot_policy(state, θ̂)`` for *that learner's* θ̂, scaled to the action space by
``task.robot_action_bound``. The envs stay the source of the state: the runner only reads
observations and info.

Speed: a unit of work is a block of run seeds (``BenchConfig.block``) × every learner. Inside a
unit every (learner, seed) episode steps in lockstep, so the robot policy (the Task planner for
the Robot) is called once per step for the whole unit instead of once per run, and the unit's
regrets are scored by one batched ``Task.regret`` call. The block size is part of the config,
never derived from ``--jobs``; a row's plan does not depend on its batch (``Task.plan``,
``tests/test_planning.py``), so results are identical across ``--jobs`` and across resumes.

The jobs live in modules of their own: ``provenance`` (the code and learner fingerprints),
``worker`` (a process's cache of envs and learners), ``episodes`` (the lockstep loop and its
records), ``pool`` (where units run); this module orchestrates.
"""

from __future__ import annotations

import datetime as _dt
import os
import time
from collections.abc import Callable

from strol_gym.benchmarks.engine.config import BenchConfig, Unit
from strol_gym.benchmarks.engine.pool import default_jobs, iter_results
from strol_gym.benchmarks.engine.provenance import (
    NUMERIC_PACKAGES,
    check_learners,
    code_fingerprint,
)
from strol_gym.benchmarks.engine.results import ResultsDir

__all__ = ["default_jobs", "run_benchmark"]


def run_benchmark(
    config: BenchConfig,
    out: str | os.PathLike,
    *,
    jobs: int = 1,
    quiet: bool = False,
    force: bool = False,
    on_unit: Callable[[Unit, int], None] | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    slurm: dict | None = None,
) -> ResultsDir:
    """Run (or resume) ``config`` into the folder ``out``; returns the folder when all is done.

    ``on_unit(unit, n_done)`` is called after each unit is stored (tests use it to simulate an
    interruption). Learners are built once up front, so a bad learner fails before any work.
    ``backend`` is ``"local"`` (``jobs`` processes) or ``"ray"`` (Ray tasks on the cluster at
    ``ray_address``, or on a local one with ``jobs`` CPUs) or ``"slurm"`` (a job array,
    ``slurm`` = ``iter_slurm``'s options); records do not depend on it.
    """
    if int(jobs) < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    from strol_gym.benchmarks.engine.backends import check_backend
    from strol_gym.benchmarks.engine.results import package_versions

    check_backend(backend, ray_address, slurm)
    config, stuck = config.with_user_specs()
    if stuck and (int(jobs) > 1 or backend != "local"):
        raise ValueError(
            f"{', '.join(stuck)} cannot reach the worker processes: it was registered as a "
            "lambda, a closure or interactive code. Register an importable object or a "
            "'module:attr' string (e.g. in a module passed to --plugin), or use --jobs 1"
        )
    versions = package_versions()
    extra = {
        "learners": check_learners(config),
        "code": code_fingerprint(),
        "numeric_packages": {k: versions.get(k) for k in NUMERIC_PACKAGES},
    }
    rd = ResultsDir.open(out, config, extra=extra, force=force)
    todo = rd.missing_units()
    started = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    t0 = time.perf_counter()
    total_runs = sum(e.runs for e in config.experiments)
    done_runs = total_runs - sum(len(u.seeds) for u in todo)
    bar = None
    if not quiet:
        from tqdm.auto import tqdm

        bar = tqdm(
            total=total_runs, initial=done_runs, unit="run", desc="strol-bench", dynamic_ncols=True
        )
    n = 0
    try:
        units = iter_results(config, todo, int(jobs), backend, ray_address, rd.path, slurm)
        for unit, records in units:
            rd.write_unit(unit, records)
            n += 1
            if bar is not None:
                exp = config.experiments[unit.experiment]
                bar.set_postfix_str(f"{exp.env}/{exp.condition.name}", refresh=False)
                bar.update(len(unit.seeds))
            if on_unit is not None:
                on_unit(unit, n)
    finally:
        if bar is not None:
            bar.close()
        rd.finish_session(started, time.perf_counter() - t0, n, int(jobs))
    return rd
