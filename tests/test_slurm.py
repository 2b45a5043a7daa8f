"""``--backend slurm`` (a submitit job array; submitit's local executor here) stores the records
``--backend local`` stores, byte for byte, and resumes after its submitting process is gone:
block files an array wrote are collected, only the missing units are submitted again."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from strol_gym.benchmarks.cli import main
from strol_gym.benchmarks.engine.config import BenchConfig
from strol_gym.benchmarks.engine.pool import new_worker
from strol_gym.benchmarks.engine.slurm import SLURM_DIR, _array_task

pytest.importorskip("submitit", reason='submitit is not installed (pip install ".[slurm]")')

RUN = ["run", "--env", "robot", "--learners", "gradient,strol", "--runs", "4", "--block", "2"]
SLURM = ["--backend", "slurm", "--slurm-executor", "local", "--jobs", "2"]


def _bytes(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((folder / "records").glob("*.json"))}


def test_slurm_array_records_equal_local_and_resume_after_the_submitter_died(tmp_path):
    local, slurm = tmp_path / "local", tmp_path / "slurm"
    assert main([*RUN, "--jobs", "1", "--quiet", "--no-plots", "--out", str(local)]) == 0
    assert len(_bytes(local)) == 2

    # The submitting process is killed once its array is submitted.
    argv = [sys.executable, "-m", "strol_gym.benchmarks", *RUN, *SLURM, "--quiet"]
    proc = subprocess.Popen([*argv, "--out", str(slurm)], cwd=tmp_path)
    logs = slurm / SLURM_DIR / "logs"
    deadline = time.monotonic() + 300
    while not list(logs.glob("*_submitted.pkl")) and time.monotonic() < deadline:
        assert proc.poll() is None, "the submitter ended before submitting"
        time.sleep(0.2)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not (slurm / "records").exists() or not _bytes(slurm)

    # One task of an array that outlived its submitter finished: its block file is there, as is
    # a stale block of another config (ignored).
    config = BenchConfig.from_dict(json.loads((local / "meta.json").read_text())["config"])
    units = config.units()
    blocks = slurm / SLURM_DIR / "blocks"
    _array_task(config.to_dict(), list(sys.path), units[0], str(blocks), new_worker)
    (blocks / f"{units[1].key}.stale.json").write_text('{"config_hash": "other"}')
    submitted = len(list(logs.glob("*_submitted.pkl")))

    # the same command again, in a fresh process as a user reruns it (this process's registries
    # hold other tests' pieces, which the code fingerprint would see)
    rerun = subprocess.run([*argv, "--no-plots", "--out", str(slurm)], cwd=tmp_path, timeout=600)
    assert rerun.returncode == 0
    assert _bytes(slurm) == _bytes(local)
    assert len(list(logs.glob("*_submitted.pkl"))) == submitted + 1  # only the missing unit
    assert not (slurm / ".lock").exists() and os.listdir(blocks)
