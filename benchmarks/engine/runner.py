"""The paired benchmark runner.

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
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import multiprocessing as mp
import os
import signal
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from strol_gym.benchmarks.engine import study_authors
from strol_gym.benchmarks.engine.conditions import env_preset
from strol_gym.benchmarks.engine.config import BenchConfig, Unit
from strol_gym.benchmarks.engine.kernels import kernel_label
from strol_gym.benchmarks.engine.results import ResultsDir

from strol_gym.learners.protocol import LearnerFailed
from strol_gym.learners.registry import make_learner
from strol_gym.metrics import cos_error, episode_regret, error, info_metrics
from strol_gym.registry import install_specs

# What a record depends on besides the run's config: every module of the strol_gym package
# except the benchmark's report-only modules (tables, plots, statistics, the CLI), plus the
# shipped data, by data package and the suffixes setup.cfg installs. ``study_authors`` computes
# a recorded value (the authors'-way correction time), so it counts.
BENCHMARK_CODE = (
    "engine",
    "engine.runner",
    "engine.config",
    "engine.conditions",
    "engine.study_authors",
)
MAPPED_PACKAGES = ("strol_gym.wrappers", "strol_gym.benchmarks")
DATA_FILES = {"strol_gym.assets": (".xml", ".npz"), "strol_gym.pretrained": (".pt", ".json")}


def _code_modules(package: str = "strol_gym") -> list[str]:
    """Names of ``package`` and all its submodules, found through the import system (so an
    editable and a wheel install list the same modules, whatever their files' layout)."""
    import importlib
    import pkgutil

    names = [package]
    pkg = importlib.import_module(package)
    found = {i.name: i.ispkg for i in pkgutil.iter_modules(pkg.__path__, package + ".")}
    if package == "strol_gym":
        # setup.cfg maps these from the repository's top level (package_dir): an editable
        # install imports them but does not list them under strol_gym's folder.
        found.update(dict.fromkeys(MAPPED_PACKAGES, True))
    for name, ispkg in sorted(found.items()):
        if name == "strol_gym.benchmarks":
            names += [f"{name}.{m}" for m in BENCHMARK_CODE]
        elif ispkg:
            names += _code_modules(name)
        else:
            names.append(name)
    return names


def code_fingerprint() -> str:
    """SHA-256 of the code and data that produce records: each strol_gym module's source (tasks,
    envs, humans, learners, wrappers, this runner and the benchmark's config and conditions)
    under its module name, and the shipped assets and weights under their package-relative
    names.

    Part of the config hash, so a results folder is never resumed with other code: a resumed
    run would otherwise mix records from two versions. Report-only modules are left out, so
    re-rendering with newer tables or plots still works. Hashing by module name, not by file
    listing, gives the same fingerprint for an editable and a wheel install of one commit.
    """
    import importlib.resources
    import importlib.util

    h = hashlib.sha256()
    for name in sorted(_code_modules()):
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None or spec.loader is None:
            raise RuntimeError(f"cannot find the source of module {name!r} to fingerprint it")
        source = spec.loader.get_data(spec.origin)  # type: ignore[attr-defined]
        h.update(f"module:{name}".encode() + b"\0" + source + b"\0")
    for package, suffixes in DATA_FILES.items():
        root = importlib.resources.files(package)
        files = sorted((f.name, f) for f in root.iterdir() if f.name.endswith(suffixes))
        for fname, f in files:
            h.update(f"data:{package}/{fname}".encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


NUMERIC_PACKAGES = ("numpy", "scipy", "torch", "gymnasium", "mujoco", "highway-env")


def learner_fingerprint(learner: Any) -> dict[str, Any]:
    """What identifies a learner's behaviour: class, config and a hash of its weights file."""
    fp: dict[str, Any] = {"class": f"{type(learner).__module__}.{type(learner).__qualname__}"}
    config = getattr(learner, "config", None)
    if callable(config):
        fp["config"] = config()
    ckpt = getattr(learner, "checkpoint", None)
    if ckpt:
        fp["weights_sha256"] = hashlib.sha256(Path(ckpt).read_bytes()).hexdigest()[:16]
    return fp


def check_learners(config: BenchConfig) -> dict[str, Any]:
    """Build every learner for every env once (before any work) and return their fingerprints.

    Raises ValueError for an unknown learner or one that cannot be built for an env's task.
    """
    import gymnasium as gym

    import strol_gym  # noqa: F401  (registers the envs)

    out: dict[str, Any] = {}
    for env_key in dict.fromkeys(e.env for e in config.experiments):
        exp = next(e for e in config.experiments if e.env == env_key)
        env = gym.make(exp.env_id, **exp.env_kwargs())
        try:
            task = env.unwrapped.task
            out[env_key] = {}
            for lr in config.learners:
                try:
                    learner = make_learner(lr, task=task, **config.kwargs_for(lr))
                except (OSError, TypeError) as e:
                    raise ValueError(f"learner {lr!r} cannot be built for {exp.env_id}: {e}") from e
                out[env_key][lr] = learner_fingerprint(learner)
        finally:
            env.close()
    return out


# ---------------------------------------------------------------------- one unit of work
class _Worker:
    """Per-process cache of envs and wrapped learners, so a unit does not rebuild them."""

    def __init__(self, config: BenchConfig) -> None:
        install_specs(config.plugins)  # the parent's user registrations, in a fresh process
        self.config = config
        self._exp: int | None = None
        self._envs: list[Any] = []
        self._wrapped: dict[str, list[Any]] = {lr: [] for lr in config.learners}

    def _prepare(self, exp_index: int, n: int) -> None:
        import gymnasium as gym
        from strol_gym.wrappers import OnlineLearningWrapper

        import strol_gym  # noqa: F401

        if self._exp != exp_index:
            self.close()
            self._exp = exp_index
        exp = self.config.experiments[exp_index]
        for lr, wrapped in self._wrapped.items():
            while len(wrapped) < n:  # an env per learner and slot: the learners run in lockstep
                env = gym.make(exp.env_id, **exp.env_kwargs())
                self._envs.append(env)
                learner = make_learner(lr, task=env.unwrapped.task, **self.config.kwargs_for(lr))
                wrapped.append(OnlineLearningWrapper(env, learner, regret=False))

    def close(self) -> None:
        for env in self._envs:
            env.close()
        self._envs, self._exp = [], None
        self._wrapped = {lr: [] for lr in self.config.learners}

    def run_unit(self, unit: Unit) -> list[dict]:
        """Every learner on every seed of ``unit``: a list of per-run records (learner-major)."""
        exp = self.config.experiments[unit.experiment]
        n = len(unit.seeds)
        self._prepare(unit.experiment, n)
        task = self._envs[0].unwrapped.task
        policy = _MemoPolicy(task) if env_preset(exp.env).robot == "task" else _zero_policy
        runs = [
            (lr, seed, wrapped)
            for lr in self.config.learners
            for seed, wrapped in zip(unit.seeds, self._wrapped[lr][:n], strict=True)
        ]
        out = _run_block(runs, exp.corrections, exp.env, exp.condition.name, policy)
        _score_regret(task, out)
        label = kernel_label()  # this process's: a Ray worker's own CPU
        for r in out:
            r["kernels"] = label
        return out


class _MemoPolicy:
    """``task.robot_policy`` on a batch, planning each distinct row once per unit.

    The policy is a deterministic function of (x, θ̂). At step 0 every learner of a run has the
    same start state and θ̂0, so only one of them pays for that plan. Rows are compared by their
    exact bytes, and a row's plan does not depend on the rest of its batch (``Task.plan``), so
    a remembered answer is the very number a fresh call would give.
    """

    def __init__(self, task: Any) -> None:
        self.task = task
        self.cache: dict[bytes, np.ndarray] = {}

    def __call__(self, x: np.ndarray, theta: np.ndarray) -> np.ndarray:
        keys = [a.tobytes() + b.tobytes() for a, b in zip(x, theta, strict=True)]
        todo: dict[bytes, int] = {}
        for i, k in enumerate(keys):
            if k not in self.cache:
                todo.setdefault(k, i)
        if todo:
            rows = list(todo.values())
            u = np.asarray(self.task.robot_policy(x[rows], theta[rows]), dtype=np.float64)
            self.cache.update(zip(todo, u.reshape(len(rows), -1), strict=True))
        return np.stack([self.cache[k] for k in keys])


def _zero_policy(x: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Action zero for every row: an env that drives its own robot (the study env's robot
    follows its plan for θ̂; the action is a residual on it) runs as the paper's robot."""
    return np.zeros_like(x)


CORRECTION_METRICS: dict[str, Callable[[dict], float]] = {
    "correction_time_authors": study_authors.correction_time,
}
"""Per-correction values summed over an episode, from the ``correction_record`` an env puts in
``info`` when a correction ends (the study env does); recorded for envs that report
``correction_time``."""


def _state(obs: Any) -> np.ndarray:
    return np.asarray(obs["state"] if isinstance(obs, dict) else obs, dtype=np.float64)


def _score_regret(task: Any, records: list[dict]) -> None:
    """Every record's regret in one batched call: the unit's planning is batched, and θ*'s plan
    from a run's x0, shared by all learners on that seed, is made once (``Task.regret``)."""
    if not records:
        return
    rows = [np.asarray([r[k] for r in records], dtype=np.float64) for k in _REGRET_INPUTS]
    for record, regret in zip(records, episode_regret(task, *rows), strict=True):
        record["regret"] = regret


_REGRET_INPUTS = ("theta_hat", "theta_star", "x0")


def _run_block(
    runs: Sequence[tuple[str, int, Any]],
    steps: int,
    env: str,
    cond: str,
    policy: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> list[dict]:
    """Lockstep episodes of ``runs`` = (learner name, run seed, its wrapped env): one policy
    call per step for all of them; a record per run, in the order given."""
    wrapped = [w for _, _, w in runs]
    seeds = [s for _, s, _ in runs]
    task = wrapped[0].unwrapped.task
    bound = np.asarray(task.robot_action_bound, dtype=np.float64)
    b = len(seeds)

    def failed(i: int, e: Exception) -> LearnerFailed:
        where = f"in run seed {seeds[i]} ({env}, condition {cond})"
        return LearnerFailed.of(str(runs[i][0]), where, e)

    obs = []
    for i, (w, s) in enumerate(zip(wrapped, seeds, strict=True)):
        try:
            obs.append(w.reset(seed=int(s))[0])
        except Exception as e:  # a user's learner may raise anything: name it and the run
            raise failed(i, e) from None
    x0 = [_state(o) for o in obs]
    thetas = [[np.array(w.learner.theta, dtype=np.float64)] for w in wrapped]
    alive = np.ones(b, dtype=bool)
    last_info: list[dict] = [{} for _ in range(b)]
    first_corr: list[Any] = [None] * b
    per_corr = [dict.fromkeys(CORRECTION_METRICS, 0.0) for _ in range(b)]
    terminated = np.zeros(b, dtype=bool)
    n_steps = np.zeros(b, dtype=int)
    for _ in range(steps):
        idx = np.flatnonzero(alive)
        if len(idx) == 0:
            break
        x = np.stack([_state(obs[i]) for i in idx])
        th = np.stack([np.asarray(wrapped[i].learner.theta, dtype=np.float64) for i in idx])
        u = policy(x, th)
        action = np.clip(u / bound, -1.0, 1.0).astype(np.float32)
        for j, i in enumerate(idx):
            try:
                o, _, term, trunc, info = wrapped[i].step(action[j])
            except Exception as e:
                raise failed(i, e) from None
            obs[i], last_info[i] = o, info
            n_steps[i] += 1
            thetas[i].append(np.array(wrapped[i].learner.theta, dtype=np.float64))
            if first_corr[i] is None and info.get("is_correction", False):
                first_corr[i] = np.asarray(info["correction"], dtype=np.float64).tolist()
            if "correction_record" in info:
                for name, fn in CORRECTION_METRICS.items():
                    per_corr[i][name] += fn(info["correction_record"])
            if term or trunc:
                alive[i] = False
                terminated[i] = bool(term)
    records = []
    for i, seed in enumerate(seeds):
        info = last_info[i]
        star = np.asarray(info["theta_star"], dtype=np.float64)
        errs = [error(star, t) for t in thetas[i]]
        coss = [cos_error(star, t) for t in thetas[i]]
        records.append(
            {
                "env": env,
                "condition": cond,
                "learner": runs[i][0],
                "seed": int(seed),
                "error": errs[-1],
                "cos_error": coss[-1],
                "regret": float("nan"),  # scored for the whole unit at once: _score_regret
                "errors": errs,
                "cos_errors": coss,
                "steps": int(n_steps[i]),
                "terminated": bool(terminated[i]),
                "theta_star": star.tolist(),
                "theta_hat": thetas[i][-1].tolist(),
                "x0": x0[i].tolist(),
                "first_correction": first_corr[i],
            }
            | {k: float(info[k]) for k in info_metrics() if k in info}  # the env's own totals
            | (per_corr[i] if "correction_time" in info else {})
        )
    return records


# ---------------------------------------------------------------------- process pool plumbing
_WORKER: _Worker | None = None


def _init_worker(config_dict: dict, parent: int | None = None) -> None:
    global _WORKER
    # Ctrl-C is the parent's to handle: it stops the pool; finished units are already stored.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent)
    _WORKER = new_worker(BenchConfig.from_dict(config_dict))


def new_worker(config: BenchConfig) -> _Worker:
    """A worker for a process of its own (a pool or Ray process): one intra-op thread."""
    _limit_threads()
    return _Worker(config)


PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int | None) -> None:
    """Have the kernel kill this worker when the process that started it dies (Linux), even by
    SIGKILL, so no orphan goes on computing and writing BrokenPipe tracebacks into the log."""
    import ctypes
    import sys

    if sys.platform != "linux":
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        return
    if parent is not None and os.getppid() != parent:  # it died before prctl took effect
        os._exit(1)


def _work(unit: Unit) -> tuple[Unit, list[dict]]:
    assert _WORKER is not None
    return unit, _WORKER.run_unit(unit)


def _limit_threads() -> None:
    """One intra-op thread per process: parallelism comes from --jobs, and reductions (torch,
    BLAS) then run in one fixed order, so every process computes bit-identical numbers."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    with contextlib.suppress(ImportError):
        import torch

        torch.set_num_threads(1)


@contextlib.contextmanager
def _single_thread_torch() -> Iterator[None]:
    try:
        import torch
    except ImportError:
        yield
        return
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def _iter_results(
    config: BenchConfig,
    units: list[Unit],
    jobs: int,
    backend: str = "local",
    ray_address: str | None = None,
) -> Iterator[tuple[Unit, list[dict]]]:
    if backend == "ray":
        from strol_gym.benchmarks.engine.backends import iter_ray

        yield from iter_ray(config, units, jobs, ray_address, new_worker)
        return
    if jobs <= 1 or len(units) <= 1:
        worker = _Worker(config)
        try:
            with _single_thread_torch():
                for u in units:
                    yield u, worker.run_unit(u)
        finally:
            worker.close()
        return
    ctx = mp.get_context("spawn")
    # The workers start with SIGINT ignored (a disposition exec keeps), so a Ctrl-C while they
    # import reaches only this process, which stops the pool: no worker tracebacks.
    with _sigint_ignored():
        pool = ctx.Pool(
            min(jobs, len(units)),
            initializer=_init_worker,
            initargs=(config.to_dict(), os.getpid()),
        )
    with pool:
        try:
            yield from pool.imap_unordered(_work, units)
        except BaseException:
            pool.terminate()
            raise


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while the block runs (in the main thread; elsewhere it cannot be set)."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


def default_jobs() -> int:
    """The CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


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
) -> ResultsDir:
    """Run (or resume) ``config`` into the folder ``out``; returns the folder when all is done.

    ``on_unit(unit, n_done)`` is called after each unit is stored (tests use it to simulate an
    interruption). Learners are built once up front, so a bad learner fails before any work.
    ``backend`` is ``"local"`` (``jobs`` processes) or ``"ray"`` (Ray tasks on the cluster at
    ``ray_address``, or on a local one with ``jobs`` CPUs); records do not depend on it.
    """
    if int(jobs) < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    from strol_gym.benchmarks.engine.backends import check_backend
    from strol_gym.benchmarks.engine.results import package_versions

    check_backend(backend, ray_address)
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
        for unit, records in _iter_results(config, todo, int(jobs), backend, ray_address):
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
