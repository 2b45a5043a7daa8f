"""Regression tests for the defects a probe of ~150 bad inputs found.

Each test names the defect it guards; every one failed before its fix. Errors must name the
argument (or the file) and its valid range; the CLI exits with status 2 and one line.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from cli_checks import cli_error

from strol_gym.benchmarks.engine.config import MAX_RUNS, paper_config
from strol_gym.benchmarks.engine.results import LOCK, META, RECORDS, ResultsDir, ResultsError
from strol_gym.humans import MAX_BETA, MAX_FRACTION, make_human
from strol_gym.learners import checkpoint as ckpt
from strol_gym.learners.network import CorrectionNet
from strol_gym.learners.registry import make_learner
from strol_gym.priors import FixedPrior, UniformPrior
from strol_gym.tasks.highway import HighwayTask
from strol_gym.tasks.robot import RobotTask

ROBOT = RobotTask()


# ---------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("human", "arg"), [("nominal", "sigma"), ("nominal", "bias"), ("boltzmann", "beta")]
)
def test_non_numeric_noise_bias_beta_name_the_argument(human, arg):
    rng = np.random.default_rng(1000)
    with pytest.raises(ValueError, match=rf"^{arg} must be a number in \["):
        make_human(human, ROBOT, np.zeros(2), rng, **{arg: "abc"})
    with pytest.raises(ValueError, match=rf"^{arg} must be a number in \["):
        gym.make("StROL-Highway-v0", person={"name": human, arg: [1, 2]})


@pytest.mark.parametrize("arg", ["sigma", "bias", "beta"])
def test_noise_bias_beta_have_an_upper_bound(arg):
    """sigma=1e308 gave infinite corrections; now it is refused, and the bound itself works."""
    rng = np.random.default_rng(1001)
    top = MAX_BETA if arg == "beta" else MAX_FRACTION
    human = "boltzmann" if arg == "beta" else "nominal"
    with pytest.raises(
        ValueError, match=rf"{arg} must be a number in \[.*{re.escape(f'{top:g}')}\]"
    ):
        make_human(human, ROBOT, np.zeros(2), rng, **{arg: 1e308})
    h = make_human(human, ROBOT, np.array([0.8, -0.8]), rng, **{arg: top})
    assert np.isfinite(h.act(ROBOT.start, np.zeros(3), np.zeros(2))).all()


def test_priors_refuse_nan():
    with pytest.raises(ValueError, match="thetas must be finite"):
        FixedPrior([[np.nan, 1.0]])
    with pytest.raises(ValueError, match="thetas must have shape"):
        FixedPrior(np.zeros((0, 2)))
    with pytest.raises(ValueError, match="finite low < high"):
        UniformPrior(2, low=-np.inf)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("alpha", np.nan),
        ("alpha", -1.0),
        ("plate", np.array([np.nan, 0.0, 0.0])),
        ("cup", np.zeros(2)),
        ("start", np.array([5.0, 0.0, 0.3])),  # outside the workspace box
        ("workspace_low", np.array([0.8, -0.55, 0.0])),  # above workspace_high in x
        ("workspace_high", np.array([0.75, 0.35, np.inf])),
        ("step_bound", 0.0),
        ("plan_step_bound", np.inf),
        ("plan_steps", 0),
        ("plan_steps", 2.5),
        ("prior", FixedPrior([[1.0, 2.0, 3.0]])),
    ],
)
def test_robot_task_validates_every_field(field, value):
    with pytest.raises(ValueError, match=field):
        RobotTask(**{field: value})


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("gap_scale", np.inf),
        ("lane_weight", np.nan),
        ("min_gap", np.nan),
        ("speed_ref", np.inf),
        ("start_speed", (20.0, np.inf)),
        ("start_x", ("a", "b")),
        ("prior", FixedPrior([[1.0, 2.0]])),
    ],
)
def test_highway_task_validates_every_field(field, value):
    with pytest.raises(ValueError, match=field):
        HighwayTask(**{field: value})


def test_env_refuses_an_action_of_shape_1_by_a():
    env = gym.make("StROL-Highway-v0")
    env.reset(seed=1002)
    try:
        with pytest.raises(ValueError, match=r"action must have shape \(2,\), got \(1, 2\)"):
            env.step(np.zeros((1, 2)))
    finally:
        env.close()


@pytest.mark.parametrize("name", ["gradient", "strol", "strol-adaptive", "bayes"])
def test_empty_batch_is_refused_and_theta_keeps_its_shape(name):
    learner = make_learner(name, ROBOT)
    before = learner.theta.copy()
    with pytest.raises(ValueError, match=r"x must have shape \(3,\) or \(B, 3\) with B >= 1"):
        learner.update(np.zeros((0, 3)), np.zeros((0, 3)))
    assert np.array_equal(learner.theta, before) and learner.theta.shape == (2,)


@pytest.mark.parametrize("name", ["strol", "e2e", "strol-adaptive", "strol-unrolled"])
def test_huge_finite_inputs_leave_theta_unchanged(name):
    learner = make_learner(name, ROBOT)
    learner.update(ROBOT.start, np.array([0.05, 0.0, 0.0]))
    before = learner.theta.copy()
    with pytest.raises(ValueError, match="non-finite θ̂"):
        learner.update(np.full(3, 1e300), np.full(3, 1e300))
    assert np.array_equal(learner.theta, before)
    assert np.isfinite(learner.update(ROBOT.start, np.zeros(3))).all()  # still usable


# ---------------------------------------------------------------------- weights
def _copy_pretrained(tmp_path, weights: str, sidecar: str):
    dst = tmp_path / f"w{Path(weights).suffix}"
    shutil.copy(ckpt.PRETRAINED_DIR / weights, dst)
    shutil.copy(ckpt.PRETRAINED_DIR / sidecar, tmp_path / "w.json")
    return dst


def test_weights_containing_nan_are_refused(tmp_path):
    model = CorrectionNet(ROBOT.network_input_dim, ROBOT.dim)
    with torch.no_grad():
        next(model.parameters())[0, 0] = float("nan")
    with pytest.raises(ValueError, match="contains NaN"):
        ckpt.save_checkpoint(tmp_path / "bad.pt", model, ROBOT, "strol")
    path = _copy_pretrained(tmp_path, "robot_strol.safetensors", "robot_strol.json")
    weights = ckpt.read_weights(path)
    key = next(iter(weights))
    weights[key][0] = float("nan")
    ckpt.write_weights(path, weights, path.suffix)
    ckpt.rehash_sidecar(path)  # the hash is right: NaN itself must be refused
    with pytest.raises(ValueError, match=rf"{path}: weight '{key}' contains NaN"):
        ckpt.load_checkpoint(path, ROBOT, "strol")
    learner = make_learner("strol", ROBOT)
    state = learner.state_dict()
    state["model"] = weights
    with pytest.raises(ValueError, match="contains NaN"):
        learner.load_state_dict(state)
    assert torch.isfinite(next(learner.model.parameters())).all()


@pytest.mark.parametrize("name", ["strol", "e2e"])
def test_failed_weights_load_leaves_the_learner_untouched(name):
    learner = make_learner(name, ROBOT)
    learner.update(ROBOT.start, np.array([0.05, 0.0, 0.0]))
    theta = learner.theta.copy()
    params = {k: v.clone() for k, v in learner.model.state_dict().items()}
    state = learner.state_dict()
    state["theta"] = np.array([5.0, 5.0])
    state["model"] = dict(list(state["model"].items())[:-1])  # one tensor missing
    with pytest.raises(ValueError, match="does not fit this learner's network"):
        learner.load_state_dict(state)
    assert np.array_equal(learner.theta, theta)
    for k, v in learner.model.state_dict().items():
        assert torch.equal(v, params[k])


def test_e2e_weights_under_a_strol_sidecar_are_refused(tmp_path):
    path = _copy_pretrained(tmp_path, "robot_e2e.safetensors", "robot_strol.json")
    with pytest.raises(ValueError, match=rf"{path}: the weights do not match their sidecar"):
        make_learner("strol", ROBOT, checkpoint=path)


def test_sidecar_without_hash_is_refused_until_rehashed(tmp_path, capsys):
    path = _copy_pretrained(tmp_path, "robot_strol.safetensors", "robot_strol.json")
    meta = json.loads((tmp_path / "w.json").read_text())
    del meta["weights_sha256"]
    (tmp_path / "w.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=r"has no weights_sha256.*--rehash"):
        ckpt.load_checkpoint(path, ROBOT, "strol")
    data = path.read_bytes()
    ckpt.main(["--rehash", str(path)])
    assert "weights_sha256" in capsys.readouterr().out
    assert path.read_bytes() == data  # the weights themselves are never rewritten
    ckpt.load_checkpoint(path, ROBOT, "strol")


def test_save_checkpoint_records_the_weights_hash(tmp_path):
    model = CorrectionNet(ROBOT.network_input_dim, ROBOT.dim)
    path = ckpt.save_checkpoint(tmp_path / "m.pt", model, ROBOT, "e2e")
    assert ckpt.read_sidecar(path)["weights_sha256"] == ckpt.weights_sha256(path)
    ckpt.load_checkpoint(path, ROBOT, "e2e")


# ---------------------------------------------------------------------- CLI
TINY = ["--env", "robot", "--runs", "1", "--corrections", "1", "--quiet", "--no-plots"]


@pytest.mark.parametrize("command", ["run", "paper"])
def test_runs_above_the_maximum_are_refused_before_any_folder(command, tmp_path, capsys):
    out = tmp_path / "out"
    argv = [command, "--env", "robot", "--runs", str(10**12), "--out", str(out)]
    assert f"--runs must be an integer in [1, {MAX_RUNS}]" in cli_error(argv, capsys)
    assert not out.exists()


MODULES = {
    "raises_on_import": ("raise RuntimeError('boom')\n", "boom"),
    "bad_syntax": ("def f(:\n", "invalid syntax"),
    "exits_on_import": ("import sys\nsys.exit(3)\n", "called sys.exit(3)"),
    "factory_raises": (
        "def make(task, **kw):\n    raise RuntimeError('factory boom')\n",
        "failed to build: RuntimeError: factory boom",
    ),
}


@pytest.mark.parametrize("module", sorted(MODULES))
def test_broken_learner_modules_exit_2_with_one_line(module, tmp_path, monkeypatch, capsys):
    source, message = MODULES[module]
    (tmp_path / f"{module}.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "out"
    argv = ["run", *TINY, "--learners", f"{module}:make", "--jobs", "1", "--out", str(out)]
    line = cli_error(argv, capsys)
    assert f"{module}:make" in line and message in line
    assert not out.exists()


def test_out_to_an_unwritable_path_exits_2(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    out = blocker / "results"
    argv = ["run", *TINY, "--learners", "gradient", "--jobs", "1", "--out", str(out)]
    assert f"--out {out}: cannot write" in cli_error(argv, capsys)


@pytest.mark.parametrize("name", ["a_file/x.pt", "weights.txt"])
def test_train_out_is_checked_before_training(name, tmp_path, monkeypatch, capsys):
    from strol_gym.learners import training

    (tmp_path / "a_file").write_text("not a folder")

    def no_training(*args, **kwargs):
        raise AssertionError("training started before --out was checked")

    monkeypatch.setattr(training, "train_correction", no_training)
    line = cli_error(["train", "--steps", "1", "--out", str(tmp_path / name)], capsys)
    assert "--out" in line


# ---------------------------------------------------------------------- results folders
def _config():
    return paper_config(["robot"], runs=2, learners=("gradient", "strol"), block=2)


def _records(config, unit):
    exp = config.experiments[unit.experiment]
    return [
        {
            "env": exp.env,
            "condition": exp.condition.name,
            "learner": learner,
            "seed": s,
            **{"error": 0.5, "cos_error": 0.1, "regret": 0.2, "steps": 1, "terminated": False},
            **{"errors": [0.5], "cos_errors": [0.1]},
        }
        for learner in config.learners
        for s in unit.seeds
    ]


def _fill(rd):
    for u in rd.config.units():
        rd.write_unit(u, _records(rd.config, u))


def test_deleted_records_folder_is_recreated_on_every_rerun(tmp_path):
    cfg = _config()
    rd = ResultsDir.open(tmp_path / "r", cfg)
    _fill(rd)
    rd.finish_session("t", 1.0, 4, 1)
    shutil.rmtree(tmp_path / "r" / RECORDS)
    for _ in range(2):  # the first rerun recomputes; later ones must keep working
        rd = ResultsDir.open(tmp_path / "r", cfg)
        assert len(rd.missing_units()) == len(cfg.units())
        _fill(rd)
        rd.finish_session("t", 1.0, 4, 1)
        assert json.loads((tmp_path / "r" / META).read_text())["status"] == "complete"
        shutil.rmtree(tmp_path / "r" / RECORDS)


def test_sessions_null_in_meta_is_repaired(tmp_path):
    cfg = _config()
    ResultsDir.open(tmp_path / "r", cfg).finish_session("t", 1.0, 0, 1)
    meta = json.loads((tmp_path / "r" / META).read_text())
    meta["sessions"] = None
    (tmp_path / "r" / META).write_text(json.dumps(meta))
    rd = ResultsDir.open(tmp_path / "r", cfg)
    rd.finish_session("t", 2.0, 0, 1)
    meta = json.loads((tmp_path / "r" / META).read_text())
    assert len(meta["sessions"]) == 1 and meta["wall_time_s"] == 2.0


@pytest.mark.parametrize("where", ["config", "experiments", "condition"])
def test_report_on_a_config_with_a_number_for_a_mapping(where, tmp_path, capsys):
    cfg = _config()
    rd = ResultsDir.open(tmp_path / "r", cfg)
    _fill(rd)
    rd.finish_session("t", 1.0, 1, 1)
    meta = json.loads((tmp_path / "r" / META).read_text())
    if where == "config":
        meta["config"] = 5
    elif where == "experiments":
        meta["config"]["experiments"] = [5]
    else:
        meta["config"]["experiments"][0]["condition"] = 5
    (tmp_path / "r" / META).write_text(json.dumps(meta))
    assert str(tmp_path / "r" / META) in cli_error(["report", str(tmp_path / "r")], capsys)


def test_binary_meta_json_is_named_in_the_error(tmp_path, capsys):
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / META).write_bytes(bytes(range(256)))
    with pytest.raises(ResultsError, match=str(tmp_path / "r" / META)):
        ResultsDir.open(tmp_path / "r", _config())
    assert str(tmp_path / "r" / META) in cli_error(["report", str(tmp_path / "r")], capsys)


def test_a_corrupt_record_never_leaves_meta_complete(tmp_path):
    rd = ResultsDir.open(tmp_path / "r", _config())
    _fill(rd)
    rd.record_path(rd.config.units()[0]).write_text("{not json")
    rd.finish_session("t", 1.0, 1, 1)
    assert json.loads((tmp_path / "r" / META).read_text())["status"] == "incomplete"
    with pytest.raises(ResultsError, match="is corrupt"):
        rd.read_records()


def test_lock_refuses_a_concurrent_run_and_takes_over_a_stale_one(tmp_path, capsys):
    cfg = _config()
    rd = ResultsDir.open(tmp_path / "r", cfg)
    rd.finish_session("t", 1.0, 0, 1)
    assert not (tmp_path / "r" / LOCK).exists()  # released at the end of a session
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / "r" / LOCK).write_text(f"{other.pid}\n")
        with pytest.raises(
            ResultsError, match=rf"in use by another strol-bench run \(host .*, pid {other.pid}"
        ):
            ResultsDir.open(tmp_path / "r", cfg)
        with pytest.raises(ResultsError, match="in use"):
            ResultsDir.open(tmp_path / "r", cfg, force=True)  # --force must not delete it
        assert (tmp_path / "r" / META).exists()
    finally:
        other.kill()
        other.wait()
    rd = ResultsDir.open(tmp_path / "r", cfg)  # its process is gone: a stale lock
    assert f"took over {tmp_path / 'r' / LOCK}" in capsys.readouterr().err
    assert json.loads((tmp_path / "r" / LOCK).read_text())["pid"] == os.getpid()
    rd.finish_session("t", 1.0, 0, 1)
