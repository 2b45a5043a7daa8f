"""Where units of work run: in this process, in a pool of spawned processes (one intra-op
thread each, killed with their parent, Ctrl-C left to the parent) or on Ray
(``strol_gym.benchmarks.engine.backends``). Records do not depend on which."""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
from collections.abc import Iterator

from strol_gym.benchmarks.engine.config import BenchConfig, Unit
from strol_gym.benchmarks.engine.record import RunRecord
from strol_gym.benchmarks.engine.worker import Worker

_WORKER: Worker | None = None


def _init_worker(config_dict: dict, parent: int | None = None) -> None:
    global _WORKER
    # Ctrl-C is the parent's to handle: it stops the pool; finished units are already stored.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent)
    _WORKER = new_worker(BenchConfig.from_dict(config_dict))


def new_worker(config: BenchConfig) -> Worker:
    """A worker for a process of its own (a pool or Ray process): one intra-op thread."""
    limit_threads()
    return Worker(config)


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


def _work(unit: Unit) -> tuple[Unit, list[RunRecord]]:
    assert _WORKER is not None
    return unit, _WORKER.run_unit(unit)


def limit_threads() -> None:
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


def iter_results(
    config: BenchConfig,
    units: list[Unit],
    jobs: int,
    backend: str = "local",
    ray_address: str | None = None,
    out: os.PathLike | None = None,
    slurm: dict | None = None,
) -> Iterator[tuple[Unit, list[RunRecord]]]:
    """``(unit, records)`` as each unit finishes; ``out`` (the results folder) and ``slurm``
    (``iter_slurm``'s options) for the Slurm backend, whose array tasks write block files."""
    if backend == "slurm":
        from pathlib import Path

        from strol_gym.benchmarks.engine.slurm import iter_slurm

        assert out is not None, "the Slurm backend collects block files in the results folder"
        yield from iter_slurm(config, units, jobs, Path(out), new_worker, **(slurm or {}))
        return
    if backend == "ray":
        from strol_gym.benchmarks.engine.backends import iter_ray

        yield from iter_ray(config, units, jobs, ray_address, new_worker)
        return
    if jobs <= 1 or len(units) <= 1:
        worker = Worker(config)
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
