"""Where a benchmark's units of work run: ``local`` processes (the default), a Ray cluster, or a
Slurm job array (``strol_gym.benchmarks.engine.slurm``, through submitit).

Both backends run the same units (blocks of run seeds × every learner) through the same worker
(``strol_gym.benchmarks.engine.pool.new_worker``, one intra-op thread per process), so the
records are identical whichever computed them, and a folder started on one backend resumes on
the other.
Ray is optional (``pip install "strol-gym[ray]"``); a local cluster listens on 127.0.0.1 only.
submitit likewise (``pip install "strol-gym[slurm]"``).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import os
import re
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

from strol_gym.benchmarks.engine.config import BenchConfig, Unit
from strol_gym.benchmarks.engine.record import RunRecord
from strol_gym.learners.protocol import LearnerFailed

BACKENDS = ("local", "ray", "slurm")
LOOPBACK = "127.0.0.1"
RAY_SINGLE_MACHINE = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
RAY_MISSING = "--backend ray needs Ray: pip install 'strol-gym[ray]'"


def add_backend_options(p: argparse.ArgumentParser) -> None:
    """``--backend`` and ``--ray-address`` for any subcommand that calls ``run_benchmark``; pass
    ``**backend_kwargs(args)`` to it."""
    p.add_argument(
        "--backend",
        choices=BACKENDS,
        default="local",
        help="where units of work run: local processes (default), Ray tasks or a Slurm job "
        "array (submitit); results are identical",
    )
    p.add_argument(
        "--slurm-executor",
        choices=("slurm", "local"),
        default=None,
        help="with --backend slurm: sbatch (default; Slurm must be installed) or submitit's "
        "local executor (no cluster)",
    )
    p.add_argument(
        "--slurm-partition",
        type=_partition,
        default=None,
        help="with --backend slurm: a partition (letters, digits, '_', '-', '.'; a "
        "comma-separated list for several)",
    )
    p.add_argument(
        "--slurm-time",
        type=_minutes,
        default=None,
        help=f"with --backend slurm: minutes per array task (default {SLURM_TIME_MIN})",
    )
    p.add_argument(
        "--ray-address",
        default=None,
        help="address of a running Ray cluster (ray.init(address=...)); default: start a local "
        "one on 127.0.0.1 with --jobs CPUs",
    )


def _minutes(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= 100_000:
        raise argparse.ArgumentTypeError(f"must be whole minutes in [1, 100000], got {text!r}")
    return value


SLURM_TIME_MIN = 60
"""Minutes per array task unless ``--slurm-time`` says otherwise."""
PARTITION = re.compile(r"^[A-Za-z0-9_.-]{1,64}(,[A-Za-z0-9_.-]{1,64}){0,31}$")
"""A Slurm partition name (or a comma-separated list): it goes into the batch script, so
nothing else (a newline would add a line to it)."""


def _partition(text: str) -> str:
    if not isinstance(text, str) or not PARTITION.match(text):
        raise argparse.ArgumentTypeError(
            "must be a partition name of letters, digits, '_', '-' and '.' (or a "
            f"comma-separated list of them), got {text!r:.80}"
        )
    return text


def backend_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The ``run_benchmark`` keyword arguments chosen by :func:`add_backend_options`' options;
    ValueError for a ``--slurm-*`` option without ``--backend slurm`` (it would do nothing)."""
    kw: dict[str, Any] = {"backend": args.backend, "ray_address": args.ray_address}
    given = [
        f"--slurm-{name}"
        for name in ("executor", "partition", "time")
        if getattr(args, f"slurm_{name}", None) is not None
    ]
    if given and args.backend != "slurm":
        raise ValueError(f"{', '.join(given)} only apply with --backend slurm")
    if args.backend == "slurm":
        kw["slurm"] = {
            "executor": args.slurm_executor or "slurm",
            "partition": args.slurm_partition,
            "time_min": args.slurm_time or SLURM_TIME_MIN,
        }
    return kw


def check_slurm(options: dict[str, Any] | None) -> None:
    """ValueError naming what is wrong with ``--backend slurm``'s options: an unknown executor,
    a partition that is not a name (:data:`PARTITION`), or the executor ``slurm`` on a machine
    without Slurm's ``sbatch`` and ``srun`` (submitit would quietly run every unit here)."""
    import shutil

    opts = options or {}
    executor = opts.get("executor", "slurm")
    if executor not in ("slurm", "local"):
        raise ValueError(f"slurm executor must be 'slurm' or 'local', got {executor!r}")
    partition = opts.get("partition")
    if partition is not None:
        try:
            _partition(partition)
        except argparse.ArgumentTypeError as e:
            raise ValueError(f"--slurm-partition {e}") from None
    missing = [tool for tool in ("sbatch", "srun") if shutil.which(tool) is None]
    if executor == "slurm" and missing:
        raise ValueError(
            f"--backend slurm needs Slurm: {' and '.join(missing)} not on PATH (install "
            "Slurm's client, or give --slurm-executor local to run the array on this machine)"
        )


def check_backend(
    backend: str, ray_address: str | None, slurm: dict[str, Any] | None = None
) -> None:
    """ValueError for an unknown backend, an address without Ray, Ray not installed, or
    Slurm's options wrong or given without ``backend='slurm'`` (:func:`check_slurm`)."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {list(BACKENDS)}, got {backend!r}")
    if ray_address is not None and backend != "ray":
        raise ValueError("ray_address is only used with backend 'ray'")
    if ray_address is not None and (not isinstance(ray_address, str) or not ray_address):
        raise ValueError(f"ray_address must be a non-empty address string, got {ray_address!r}")
    if backend == "ray" and importlib.util.find_spec("ray") is None:
        raise ValueError(RAY_MISSING)
    if slurm is not None and backend != "slurm":
        raise ValueError("slurm options are only used with backend 'slurm'")
    if backend == "slurm" and importlib.util.find_spec("submitit") is None:
        raise ValueError("--backend slurm needs submitit: pip install 'strol-gym[slurm]'")
    if backend == "slurm":
        check_slurm(slurm)
    if ray_address is not None:
        check_reachable(ray_address)  # before any work: Ray itself retries for minutes


RAY_CONNECT_TIMEOUT = 10.0
"""Seconds to wait for a Ray cluster's address to accept a connection (Ray itself retries for
minutes)."""


HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes.fromhex("000000040000000000")
"""What an HTTP/2 client sends first (the connection preface, then an empty SETTINGS frame)."""


def check_reachable(address: str, timeout: float = RAY_CONNECT_TIMEOUT) -> None:
    """ValueError naming ``address`` unless a Ray cluster's GCS answers there within
    ``timeout`` s: a TCP connection alone is not enough (any service accepts one, and Ray would
    then retry for minutes). Ray's GCS speaks gRPC, i.e. HTTP/2, whose server answers a client's
    connection preface with a SETTINGS frame (RFC 9113, 3.4): that answer is what is checked.

    Only for ``host:port`` addresses; ``auto`` and ``ray://`` addresses are left to Ray.
    """
    import socket

    if address == "auto" or "://" in address:
        return
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"--ray-address must be HOST:PORT (port in [1, 65535]), got {address!r}")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout) as s:
            s.settimeout(timeout)
            s.sendall(HTTP2_PREFACE)
            head = b""
            while len(head) < 9:  # a frame header: length (3), type (1), flags (1), stream (4)
                more = s.recv(9 - len(head))
                if not more:
                    break
                head += more
    except OSError as e:
        raise ValueError(
            f"--ray-address {address}: no Ray cluster reachable there within {timeout:g} s ({e})"
        ) from None
    if len(head) < 9 or head[3] != 0x04:
        raise ValueError(
            f"--ray-address {address}: the service there is not a Ray cluster (it does not speak "
            f"gRPC/HTTP-2; it answered {head[:16]!r}); give the head node's GCS address, "
            "HOST:6379 by default"
        )


# ---------------------------------------------------------------------- inside a Ray worker
_CACHE: dict[str, Any] = {}


def _ray_unit(
    config_dict: dict, sys_path: list[str], unit: Unit, make_worker: Callable[[BenchConfig], Any]
) -> tuple[Unit, list[RunRecord]]:
    """One unit in a Ray worker process. The worker keeps its envs and learners between units of
    the same config (as a local pool process does), keyed by the config's JSON."""
    for entry in sys_path:  # the driver's path: user plugins given as .py files import here
        if entry not in sys.path:
            sys.path.append(entry)
    key = hashlib.sha256(json.dumps(config_dict, sort_keys=True).encode()).hexdigest()
    if _CACHE.get("key") != key:
        if "worker" in _CACHE:
            _CACHE.pop("worker").close()
        _CACHE["worker"] = make_worker(BenchConfig.from_dict(config_dict))
        _CACHE["key"] = key
    return unit, _CACHE["worker"].run_unit(unit)


# ---------------------------------------------------------------------- on the driver
RAY_INIT_DEADLINE = 20.0
"""Seconds ``ray.init`` may take to join the cluster at ``--ray-address``: a service that
answers like gRPC but is not Ray's (any HTTP/2 server) passes :func:`check_reachable`, and Ray
then retries for minutes."""


def _init_within(ray: Any, deadline: float, **kwargs: Any) -> None:
    """``ray.init(**kwargs)`` in a thread, waited for ``deadline`` s: ValueError naming the
    address if it has not joined by then (the thread is left to Ray's own retries; it holds
    nothing of ours, and the process ends as the command does)."""
    box: dict[str, BaseException] = {}

    def init() -> None:
        try:
            ray.init(**kwargs)
        except BaseException as e:  # handed to the caller
            box["error"] = e

    thread = threading.Thread(target=init, name="ray.init", daemon=True)
    thread.start()
    thread.join(deadline)
    if thread.is_alive():
        raise ValueError(
            f"--ray-address {kwargs.get('address')}: no Ray cluster answered within "
            f"{deadline:g} s (the service there accepts connections but did not let Ray join)"
        )
    if "error" in box:
        raise box["error"]


def _start_ray(jobs: int, address: str | None) -> bool:
    """Connect to ``address`` or start a local cluster; True when this call started Ray (and
    so must shut it down)."""
    common: dict[str, Any] = {
        "include_dashboard": False,
        "log_to_driver": False,
        "configure_logging": False,
    }
    if address is not None:
        import ray

        if ray.is_initialized():
            return False
        _init_within(ray, RAY_INIT_DEADLINE, address=address, **common)
        return True
    # Ray resolves 127.0.0.1 to the host's network address, and its servers then listen on
    # every interface, unless its single-machine mode is on: read at import by this process,
    # and from the environment by the cluster's processes this starts.
    os.environ[RAY_SINGLE_MACHINE] = "0"
    import ray
    from ray._private import ray_constants

    if ray.is_initialized():
        return False
    ray_constants.ENABLE_RAY_CLUSTER = False
    ray.init(num_cpus=jobs, _node_ip_address=LOOPBACK, **common)
    return True


def iter_ray(
    config: BenchConfig,
    units: list[Unit],
    jobs: int,
    address: str | None,
    make_worker: Callable[[BenchConfig], Any],
) -> Iterator[tuple[Unit, list[RunRecord]]]:
    """Run ``units`` as Ray tasks (one CPU each) and yield ``(unit, records)`` as they finish.
    ``make_worker(config)`` builds a Ray process's worker (the runner's, passed in: a backend
    does not import the runner).

    On an error or an interrupt the pending tasks are cancelled; a cluster started here is shut
    down when the iteration ends.
    """
    import ray

    started = _start_ray(jobs, address)
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(_ray_unit)
        config_ref = ray.put(config.to_dict())
        pending = [task.remote(config_ref, list(sys.path), u, make_worker) for u in units]
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                try:
                    result = ray.get(done[0])
                except ray.exceptions.RayTaskError as e:  # one line, as with local workers
                    if isinstance(e.cause, LearnerFailed):
                        raise e.cause from None
                    raise
                yield result
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise
    finally:
        if started:
            ray.shutdown()
