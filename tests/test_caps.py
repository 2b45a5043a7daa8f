"""Every size bounded by one cap table (``strol_gym.limits``), checked where it enters and
before anything is allocated; liftable from Python and by --allow-large (issue 31, items 5, 6)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from cli_checks import cli_error

from strol_gym import checks, limits
from strol_gym.benchmarks.engine.config import MAX_TOTAL_RUNS, paper_config
from strol_gym.benchmarks.engine.results import META, ResultsDir, ResultsError
from strol_gym.humans import make_human
from strol_gym.learners import checkpoint as ckpt
from strol_gym.learners.registry import make_learner
from strol_gym.tasks import make_task
from strol_gym.wrappers.session_log import SessionLogError, read_session

CAP = "a fixed cap; --allow-large or limits.lift"


@pytest.fixture(autouse=True)
def _caps_in_force(monkeypatch):
    monkeypatch.delenv(limits.ENV_VAR, raising=False)
    limits.lift(False)
    yield
    limits.lift(False)


def test_learner_and_human_sizes_are_capped_in_the_api_and_liftable():
    task = make_task("highway")
    with pytest.raises(
        ValueError, match=rf"^n_particles must be an integer in \[1, 200,000\] \({CAP}"
    ):
        make_learner("bayes", task, n_particles=1e9)
    with pytest.raises(ValueError, match=r"^n_candidates must be an integer in \[1, 8,192\]"):
        make_learner("mof", task, n_candidates=10**9)
    with pytest.raises(ValueError, match=r"^n_candidates must be"):
        make_human("nominal", task, np.zeros(task.dim), np.random.default_rng(0), n_candidates=1e9)
    with pytest.raises(checks.ArgumentTypeError, match=r"^n_particles must be an integer"):
        make_learner("bayes", task, n_particles="many")  # the one vocabulary of strol_gym.checks
    with limits.lifted():  # lifted: the same size is built
        assert make_learner("bayes", task, n_particles=200_001).n_particles == 200_001
    with pytest.raises(ValueError, match="n_particles"):
        make_learner("bayes", task, n_particles=200_001)  # restored after the block


def test_num_envs_is_capped_before_the_envs_are_built():
    with pytest.raises(ValueError, match=r"num_envs must be an integer in \[1, 16,384\]"):
        gym.make_vec("StROL-Highway-v0", num_envs=10**7, vectorization_mode="vector_entry_point")


@pytest.mark.parametrize(
    ("argv", "flag"),
    [
        (["run", "--env", "robot", "--block", "1025"], "--block must be at most 1,024"),
        (["run", "--env", "robot", "--jobs", "100000"], "--jobs must be at most"),
        (["lambda", "--lambdas", ",".join(["1"] * 1001)], "--lambdas must be at most 1,000"),
        (["train", "--task", "robot", "--threads", "100000"], "--threads must be at most 1,024"),
        (["export", "strol/x-v0", "--env", "robot", "--corrections", "100000"], "--corrections"),
        (
            [
                "run",
                "--env",
                "highway",
                "--learners",
                "bayes,gradient",
                "--learner-kwargs",
                '{"bayes": {"n_particles": 1e9}}',
            ],
            "n_particles must be an integer in [1, 200,000]",
        ),
        (
            ["run", "--env", "robot", "--human-kwargs", '{"n_candidates": 1e9}'],
            "human_kwargs['n_candidates'] must be an integer in [1, 8,192]",
        ),
        (  # train sets n_candidates itself (--candidates): once, not a traceback
            ["train", "--task", "robot", "--human-kwargs", '{"n_candidates": 1e9}'],
            "human_kwargs must not hold 'n_candidates' in training",
        ),
    ],
    ids=[
        *("block", "jobs", "lambdas", "threads", "export-corrections", "n_particles", "human"),
        "train-human",
    ],
)
def test_cli_sizes_are_refused_in_one_line(argv, flag, tmp_path, capsys):
    out = [] if argv[0] == "export" else ["--out", str(tmp_path / "o")]
    if argv[0] == "train":
        out = ["--out", str(tmp_path / "o.safetensors")]
    assert flag in cli_error([*argv, *out], capsys)


def test_checkpoint_hashes_read_in_chunks(tmp_path, monkeypatch):
    pt = tmp_path / "w.pt"
    pt.write_bytes(bytes(range(256)) * 40)
    ckpt.sidecar_path(pt).write_text("{}")
    want = hashlib.sha256(pt.read_bytes()).hexdigest()
    monkeypatch.setattr(ckpt, "HASH_CHUNK", 1000)
    monkeypatch.setattr(Path, "read_bytes", lambda self: pytest.fail("read whole"))
    assert ckpt.weights_sha256(pt) == want
    assert len(ckpt.checkpoint_sha256(pt)) == 64


def test_a_long_session_log_line_is_refused_by_file_and_line(tmp_path):
    log = tmp_path / "s.jsonl"
    log.write_bytes(b"[" + b"1," * limits.CAPS["session_line_bytes"] + b"1]\n")
    with pytest.raises(SessionLogError, match=rf"{log}:1: a line longer than 1,048,576 bytes"):
        read_session(log)


def test_a_meta_json_planning_too_many_runs_is_refused(tmp_path):
    cfg = paper_config(["robot"], runs=2, learners=("gradient", "strol"), block=2)
    rd = ResultsDir.open(tmp_path / "r", cfg)
    rd.finish_session("t", 1.0, 0, 1)
    meta = json.loads((rd.path / META).read_text())
    exp = meta["config"]["experiments"][0]
    meta["config"]["experiments"] = [
        {**exp, "condition": {**exp["condition"], "name": f"c{i}"}, "runs": 1_000_000}
        for i in range(300)
    ]
    (rd.path / META).write_text(json.dumps(meta))
    with pytest.raises(ResultsError, match=f"at most {MAX_TOTAL_RUNS} runs in all"):
        ResultsDir.load(rd.path)


# ---------------------------------------------------------------------- Minari headers
minari = pytest.importorskip("minari")


def test_minari_sizes_are_checked_before_minari_allocates(tmp_path, monkeypatch):
    import h5py
    from test_minari import robot_session

    from strol_gym.benchmarks.sessions.dataset_gate import DatasetRefused
    from strol_gym.benchmarks.sessions.export import read_dataset

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    log = robot_session(tmp_path / "s.jsonl")
    from strol_gym.benchmarks import cli

    assert cli.main(["export", "strol/caps-v0", "--log", str(log)]) == 0
    data = tmp_path / "minari" / "strol" / "caps-v0" / "data"
    read_dataset(str(data.parent))  # as exported: read
    meta_path = data / "metadata.json"
    meta = json.loads(meta_path.read_text())
    meta_path.write_text(json.dumps({**meta, "total_episodes": 10**12}))
    with pytest.raises(
        DatasetRefused, match=r"total_episodes must be an integer in \[0, 1,000,000\]"
    ):
        read_dataset(str(data.parent))
    meta_path.write_text(json.dumps(meta))
    with h5py.File(data / "main_data.hdf5", "a") as f:
        f["episode_0"].create_dataset("huge", shape=(2 * 10**9, 3), dtype="f8", chunks=(1024, 3))
    assert (data / "main_data.hdf5").stat().st_size < 10**6  # declared, not stored
    with pytest.raises(DatasetRefused, match=r"array episode_0/huge \(2000000000, 3\) is larger"):
        read_dataset(str(data.parent))
