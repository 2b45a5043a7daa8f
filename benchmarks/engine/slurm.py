"""``--backend slurm``: the units of work as a Slurm job array, through submitit.

Each array task runs one unit (a block of run seeds × every learner) with the worker the local
pool uses, so its records are the local backend's bytes, and writes them to a block file of its
own (``<out>/.slurm/blocks/<unit>.<task>.json``, written to a temporary name and renamed). Only
the collecting process (the one that ran ``strol-bench``, holding the folder's lock) stores
records in ``records/``: it reads each block file (JSON, checked like a record file) as it
appears. A rerun of the same command collects the block files already there (an array that
outlived its submitting process) and submits only the units still missing; a unit computed twice
gives the same bytes, and the first block file found is used.

submitit hands each task its arguments as a pickle it wrote itself; this module never reads
submitit's result pickles: what comes back is the JSON block file. ``executor="local"`` runs the
array with submitit's local executor (no cluster): how CI tests it.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from strol_gym.benchmarks.engine.config import BenchConfig, Unit
from strol_gym.benchmarks.engine.record import RunRecord
from strol_gym.benchmarks.engine.results import ResultsError, write_json_atomic
from strol_gym.files import read_regular, temp_tag

SLURM_DIR = ".slurm"
EXECUTORS = ("slurm", "local")
MAX_BLOCK_BYTES = 256 * 2**20


def _array_task(
    config_dict: dict,
    sys_path: list[str],
    unit: Unit,
    blocks: str,
    make_worker: Callable[[BenchConfig], Any],
) -> str:
    """One array task: run ``unit`` with ``make_worker(config)``'s worker (the local pool's,
    passed in: a backend does not import the pool) and write its block file; its name."""
    for entry in sys_path:  # the submitter's path: user plugins given as .py files import here
        if entry not in sys.path:
            sys.path.append(entry)
    config = BenchConfig.from_dict(config_dict)
    worker = make_worker(config)
    try:
        records = worker.run_unit(unit)
    finally:
        worker.close()
    path = Path(blocks) / f"{unit.key}.{temp_tag()}-{uuid.uuid4().hex[:8]}.json"  # host-pid
    payload = {"config_hash": config.hash(), "unit": unit.key, "records": records}
    write_json_atomic(path, payload)
    return path.name


def _read_block(path: Path, unit: Unit, config_hash: str) -> list[RunRecord] | None:
    """The records of a block file, or None if it is not a complete block of ``unit`` for this
    config (a leftover of another config, a torn copy): it is then ignored and recomputed."""
    try:
        payload = json.loads(read_regular(path, MAX_BLOCK_BYTES, "block file").decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(payload, dict) or payload.get("config_hash") != config_hash:
        return None
    records = payload.get("records")
    if payload.get("unit") != unit.key or not isinstance(records, list):
        return None
    if not all(isinstance(r, dict) and r.get("seed") in unit.seeds for r in records):
        return None
    return records


def _collect(
    blocks: Path, want: dict[str, Unit], config_hash: str
) -> Iterator[tuple[Unit, list[RunRecord]]]:
    for path in sorted(blocks.glob("*.json")):
        key = path.name.split(".", 1)[0]
        if key in want:
            records = _read_block(path, want[key], config_hash)
            if records is not None:
                yield want.pop(key), records


def iter_slurm(
    config: BenchConfig,
    units: list[Unit],
    jobs: int,
    out: Path,
    make_worker: Callable[[BenchConfig], Any],
    executor: str = "slurm",
    partition: str | None = None,
    time_min: int = 60,
    poll_s: float = 2.0,
) -> Iterator[tuple[Unit, list[RunRecord]]]:
    """Run ``units`` as one job array (at most ``jobs`` tasks at once), each with
    ``make_worker(config)``'s worker, and yield ``(unit, records)`` as their block files appear
    in ``out``."""
    import submitit

    base = Path(out) / SLURM_DIR
    blocks = base / "blocks"
    blocks.mkdir(parents=True, exist_ok=True)
    config_hash = config.hash()
    want = {u.key: u for u in units}
    yield from _collect(blocks, want, config_hash)  # an earlier array's finished tasks
    if not want:
        return
    params: dict[str, Any] = {"timeout_min": int(time_min), "cpus_per_task": 1}
    if executor == "slurm":
        params["slurm_array_parallelism"] = int(jobs)
        if partition:
            params["slurm_partition"] = partition
    todo = list(want.values())
    n = len(todo)
    cfg, path = config.to_dict(), list(sys.path)
    where, make = [str(blocks)] * n, [make_worker] * n
    echoed = io.StringIO()  # submitit echoes a failing sbatch's stderr: said once, below
    try:
        with contextlib.redirect_stderr(echoed):
            # named, never None: AutoExecutor(cluster=None) would run every unit here instead
            ex = submitit.AutoExecutor(folder=base / "logs", cluster=executor)
            ex.update_parameters(name="strol-bench", **params)
            submitted = ex.map_array(_array_task, [cfg] * n, [path] * n, todo, where, make)
    except (RuntimeError, OSError) as e:  # no srun, sbatch failed (submitit's FailedJobError)
        said = " ".join(str(e).split())
        raise ResultsError(f"the Slurm array could not be submitted: {said[:400]}") from None
    sys.stderr.write(echoed.getvalue())
    try:
        while want:
            yield from _collect(blocks, want, config_hash)
            if want and all(job.done() for job in submitted):
                yield from _collect(blocks, want, config_hash)  # a file renamed just now
                if want:
                    failed = sorted(want)
                    logs = [str(j.paths.stderr) for j in submitted][:2]
                    raise ResultsError(
                        f"{len(failed)} unit(s) of the Slurm array wrote no block file "
                        f"({', '.join(failed[:5])}); see the tasks' logs, e.g. {', '.join(logs)}"
                    )
            time.sleep(poll_s if want else 0)
    except BaseException:
        if executor == "local":  # a local array dies with its collector, as a local pool does
            for job in submitted:
                job.cancel(check=False)
        raise


__all__ = ["EXECUTORS", "SLURM_DIR", "iter_slurm"]
