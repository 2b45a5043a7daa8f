"""Offline training of ĝ (Algorithm 1), checkpoints, the CLI and the shipped weights."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

import numpy as np
import pytest
import safetensors.torch
import torch
from strol_gym.benchmarks.train import add_train_arguments, main

from strol_gym import RobotTask
from strol_gym.learners.checkpoint import (
    find_pretrained,
    load_checkpoint,
    read_sidecar,
    save_checkpoint,
)
from strol_gym.learners.correction import E2ELearner, StROLLearner
from strol_gym.learners.rules import GradientLearner
from strol_gym.learners.simulate import simulate_errors
from strol_gym.learners.training import (
    TrainConfig,
    heldout_lyapunov,
    sample_batch,
    train_correction,
)

TASK = RobotTask()
SHORT = {"steps": 80, "batch": 64, "n_candidates": 64, "hidden": (64, 64, 32, 16)}


@pytest.fixture(scope="module")
def short_run():
    return train_correction(TASK, quiet=True, seed=10_000, **SHORT)


def test_short_training_lowers_loss_and_beats_gradient_on_heldout(short_run):
    model, history = short_run
    loss = history["loss"]
    assert loss.shape == (SHORT["steps"],)
    assert loss[-20:].mean() < loss[:10].mean()
    check = heldout_lyapunov(TASK, model, TrainConfig(**SHORT), seed=10_001, n=4000)
    assert check["trained"] < check["gradient"] < 0


def test_training_is_deterministic(short_run):
    model, history = short_run
    again, history2 = train_correction(TASK, quiet=True, seed=10_000, **SHORT)
    np.testing.assert_array_equal(history["loss"], history2["loss"])
    for (k, v), (k2, v2) in zip(
        model.state_dict().items(), again.state_dict().items(), strict=True
    ):
        assert k == k2 and torch.equal(v, v2)
    _other, history3 = train_correction(TASK, quiet=True, seed=10_001, **{**SHORT, "steps": 5})
    assert not np.array_equal(history["loss"][:5], history3["loss"])


def test_training_leaves_torch_settings_alone():
    threads, det = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    state = torch.random.get_rng_state()
    train_correction(TASK, quiet=True, steps=2, batch=8, threads=1, hidden=(8,))
    assert torch.get_num_threads() == threads
    assert torch.are_deterministic_algorithms_enabled() == det
    assert torch.equal(torch.random.get_rng_state(), state)


def test_sample_batch_shapes_and_human_models():
    rng = np.random.default_rng(0)
    for human in ("nominal", "boltzmann"):
        for sampling in ("path", "prior-mean", "prior"):
            cfg = TrainConfig(human=human, theta_sampling=sampling, robot_action="uniform")
            b = sample_batch(TASK, rng, 7, cfg)
            assert b["z"].shape == (7, TASK.network_input_dim)
            assert b["g"].shape == b["e"].shape == (7, 2)
            np.testing.assert_allclose(b["e"], b["theta_star"] - b["theta"])
    b = sample_batch(TASK, rng, 5, TrainConfig(theta_sampling="prior-mean"))
    np.testing.assert_array_equal(b["theta"], np.zeros((5, 2)))
    np.testing.assert_array_equal(b["u_r"], np.zeros((5, 3)))


def test_e2e_training_runs_with_boltzmann_human():
    _model, history = train_correction(
        TASK, quiet=True, kind="e2e", human="boltzmann", steps=3, batch=8, hidden=(8,)
    )
    assert np.isfinite(history["loss"]).all()
    assert history["config"]["human"] == "boltzmann"


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("kind", "x", "kind must be one of"),
        ("sigma", -0.1, "sigma"),
        ("steps", 0, "steps must be"),
        ("theta_sampling", "foo", "theta_sampling"),
        ("lr", 0.0, "lr must be"),
        ("bound", "sphere", "bound"),
    ],
)
def test_config_validation(field, value, match):
    with pytest.raises(ValueError, match=match):
        TrainConfig(**{field: value})


# ------------------------------------------------------------------ checkpoints
@pytest.mark.parametrize("suffix", [".safetensors", ".pt"])
def test_checkpoint_round_trip_and_sidecar(short_run, tmp_path, suffix):
    """Both formats round-trip: safetensors (the default) and a user's own torch .pt."""
    model, _history = short_run
    cfg = TrainConfig(**SHORT)
    path = save_checkpoint(tmp_path / f"r{suffix}", model, TASK, "strol", cfg.to_dict(), {"x": 1})
    if suffix == ".pt":
        weights = torch.load(path, weights_only=True)  # plain tensors, no pickled objects
    else:
        weights = safetensors.torch.load_file(path)  # no unpickler involved at all
    assert all(isinstance(v, torch.Tensor) for v in weights.values())
    meta = read_sidecar(path)
    assert meta["task"]["task_id"] == "StROL-Robot-v0" and meta["task"]["version"] == 0
    assert meta["task"]["feature_names"] == list(TASK.feature_names)
    assert meta["task"]["network_input_dim"] == TASK.network_input_dim
    assert meta["training"]["seed"] == 10_000 and "torch" in meta["versions"]
    loaded, _ = load_checkpoint(path, TASK, kind="strol")
    rng = np.random.default_rng(5)
    x, u_h = TASK.sample_start(rng, 20), TASK.candidate_actions(rng, 20, 1)[:, 1]
    u_r = np.zeros((20, 3))
    a = StROLLearner(TASK, model=model).update(x, u_h, u_r)
    b = StROLLearner(TASK, checkpoint=path).update(x, u_h, u_r)
    np.testing.assert_array_equal(a, b)
    assert isinstance(loaded.raw(torch.zeros(1, 6)), torch.Tensor)


def test_checkpoint_mismatch_says_what_differs(short_run, tmp_path):
    model, _ = short_run
    path = save_checkpoint(tmp_path / "r.safetensors", model, TASK, "strol")
    with pytest.raises(ValueError, match=r"alpha: checkpoint has 2\.0, task has 1\.0"):
        load_checkpoint(path, RobotTask(alpha=1.0))
    with pytest.raises(ValueError, match="kind: checkpoint has 'strol', expected 'e2e'"):
        E2ELearner(TASK, checkpoint=path)
    moved_cup = RobotTask(cup=np.array([0.6, -0.4, 0.1]))
    with pytest.raises(ValueError, match=r"geometry\.cup: checkpoint has \[0\.7, -0\.45"):
        load_checkpoint(path, moved_cup)
    meta = json.loads(path.with_suffix(".json").read_text())
    meta["task"]["feature_names"] = ["a", "b"]
    path.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="feature_names"):
        load_checkpoint(path, TASK)
    path.with_suffix(".json").unlink()
    with pytest.raises(FileNotFoundError, match="sidecar"):
        load_checkpoint(path, TASK)


# ------------------------------------------------------------------ CLI
def test_cli_trains_and_saves(tmp_path, capsys):
    out = tmp_path / "cli.safetensors"
    main(
        [
            "--task",
            "robot",
            "--kind",
            "e2e",
            "--steps",
            "3",
            "--batch",
            "8",
            "--quiet",
            "--candidates",
            "16",
            "--heldout",
            "50",
            "--out",
            str(out),
            "--seed",
            "10007",
        ]
    )
    text = capsys.readouterr().out
    assert "held-out eq. M5 term" in text and str(out) in text
    meta = read_sidecar(out)
    assert meta["kind"] == "e2e" and meta["training"]["seed"] == 10007
    assert set(meta["heldout_lyapunov"]) >= {"trained", "gradient", "seed"}
    assert np.isfinite(meta["final_loss"])


def test_add_train_arguments_fits_a_subcommand():
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="cmd")
    add_train_arguments(sub.add_parser("train"))
    args = parser.parse_args(["train", "--kind", "e2e", "--sigma", "0.1"])
    assert args.kind == "e2e" and args.sigma == 0.1 and args.steps == 500


def test_module_entry_point_help():
    res = subprocess.run(
        [sys.executable, "-m", "strol_gym.benchmarks.train", "--help"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "--kind" in res.stdout and "--sigma" in res.stdout


# ------------------------------------------------------------------ shipped weights
@pytest.mark.parametrize("kind", ["strol", "e2e"])
def test_shipped_weights_match_training_condition(kind):
    path = find_pretrained(TASK, kind)
    meta = read_sidecar(path)
    assert path.name == f"robot_{kind}.safetensors"
    assert meta["training"]["sigma"] == 0.25 and meta["training"]["bias"] == 0.0
    assert meta["training"]["seed"] >= 10_000  # disjoint from evaluation seeds 0, 1, ...
    assert meta["prior"]["name"] == "bimodal"
    assert meta["heldout_lyapunov"]["trained"] < meta["heldout_lyapunov"]["gradient"]
    assert path.stat().st_size < 1_000_000


def test_shipped_strol_beats_gradient_in_task_level_simulation():
    learners = {"gradient": GradientLearner(TASK), "strol": StROLLearner(TASK)}
    errors = simulate_errors(TASK, learners, n_runs=200, sigma=0.25, seed=0)
    assert errors["strol"].mean() < errors["gradient"].mean()
