"""strol-unrolled: ĝ on (x, u_H, θ̂) trained through K unrolled updates; weights checked at load."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import torch
from test_learners import LinearTask

import strol_gym
from strol_gym import RobotTask
from strol_gym.learners.checkpoint import PRETRAINED_DIR, input_dim
from strol_gym.learners.correction import UnrolledStROLLearner
from strol_gym.learners.training import (
    TrainConfig,
    heldout_unrolled,
    sample_batch,
    train_correction,
    unroll,
    unrolled_loss,
)
from strol_gym.tasks.highway import HighwayTask

SMALL = {"steps": 4, "batch": 16, "hidden": (16,), "n_candidates": 16}


def test_k_must_be_at_least_one():
    for bad in (0, -2, 1.5):
        with pytest.raises(ValueError, match="unroll"):
            TrainConfig(kind="strol-unrolled", unroll=bad)


def test_one_unrolled_step_is_algorithm_1s_loss():
    # With K = 1 the K-step loss equals eq. M7 on the same batch: the trainer generalises it.
    task = LinearTask()
    config = TrainConfig(kind="strol-unrolled", unroll=1, **SMALL)
    torch.manual_seed(0)
    model, _ = train_correction(task, config, quiet=True)
    batch = sample_batch(task, np.random.default_rng(5), 64, config)
    theta0, theta1 = unroll(task, model, config, batch, np.random.default_rng(6))
    g = torch.as_tensor(batch["g"], dtype=torch.float32)
    g_tilde = (theta1 - theta0) / task.alpha
    e = torch.as_tensor(batch["e"], dtype=torch.float32)
    m7 = (task.alpha**2 * (g_tilde**2).sum(-1) - 2 * task.alpha * (e * g_tilde).sum(-1)).mean()
    got = unrolled_loss(batch["theta_star"], theta0, theta1)
    assert got.item() == pytest.approx(m7.item(), abs=1e-5)
    z = torch.as_tensor(batch["z"], dtype=torch.float32)  # (x, u_H) then θ
    with torch.no_grad():
        np.testing.assert_allclose(g + model(z, g), g_tilde, atol=1e-5)


def test_training_is_seeded_and_conditions_on_theta():
    task = LinearTask()
    a, ha = train_correction(
        task, kind="strol-unrolled", unroll=3, seed=11_000, quiet=True, **SMALL
    )
    b, hb = train_correction(
        task, kind="strol-unrolled", unroll=3, seed=11_000, quiet=True, **SMALL
    )
    np.testing.assert_array_equal(ha["loss"], hb["loss"])
    for key, value in a.state_dict().items():
        assert torch.equal(value, b.state_dict()[key])
    assert a.in_dim == input_dim(task, "strol-unrolled") == task.network_input_dim + task.dim
    learner = UnrolledStROLLearner(task, model=a)
    x, u = np.array([0.3, -0.2, 0.1]), np.array([0.05, 0.02, 0.0])
    g = task.g(x[None], u[None], np.zeros((1, 3)))
    moved = [
        learner.correction(x[None], u[None], np.zeros((1, 3)), th[None])
        for th in (np.zeros(2), np.array([3.0, -3.0]))
    ]
    assert not np.allclose(moved[0], moved[1])  # ĝ depends on θ̂
    for m in moved:
        assert np.linalg.norm(m) <= np.linalg.norm(g)


@pytest.mark.parametrize("task", [RobotTask(), HighwayTask()], ids=["robot", "highway"])
def test_shipped_weights_load_and_beat_gradient_after_k_updates(task):
    learner = strol_gym.make_learner("strol-unrolled", task=task)
    assert learner.checkpoint_meta["kind"] == "strol-unrolled"
    config = TrainConfig(**learner.checkpoint_meta["training"] | {"hidden": learner.model.hidden})
    assert 11_000 <= config.seed <= 11_999 and config.unroll > 1
    check = heldout_unrolled(task, learner.model, config, seed=11_999, n=300)
    assert check["trained"] < check["gradient"]
    rng = np.random.default_rng(0)
    x = task.sample_start(rng, 64)
    u = 3 * task.candidate_actions(rng, 64, 1)[:, 1]
    theta = 2 * rng.standard_normal((64, task.dim))
    g_hat = learner.correction(x, u, np.zeros_like(u), theta)
    g = task.g(x, u, np.zeros_like(u))
    assert np.all(np.linalg.norm(g_hat, axis=1) <= np.linalg.norm(g, axis=1))


def test_weights_of_another_kind_or_task_are_refused_naming_the_file(tmp_path):
    strol_weights = PRETRAINED_DIR / "robot_strol.safetensors"
    with pytest.raises(ValueError, match=r"robot_strol\.safetensors.*kind: checkpoint has 'strol'"):
        UnrolledStROLLearner(RobotTask(), checkpoint=strol_weights)
    for ext in (".safetensors", ".json"):
        shutil.copy(PRETRAINED_DIR / f"highway_strol-unrolled{ext}", tmp_path / f"w{ext}")
    with pytest.raises(ValueError, match=r"w\.safetensors.*task_id"):
        UnrolledStROLLearner(RobotTask(), checkpoint=tmp_path / "w.safetensors")
    with pytest.raises(ValueError, match=r"robot_strol-unrolled\.safetensors.*kind"):
        strol_gym.make_learner(
            "strol",
            task=RobotTask(),
            checkpoint=PRETRAINED_DIR / "robot_strol-unrolled.safetensors",
        )


def test_training_cli_rejects_k_below_one_with_status_2(capsys):
    from strol_gym.benchmarks import train as training

    with pytest.raises(SystemExit) as e:
        training.main(["--kind", "strol-unrolled", "-K", "0", "--out", "never.safetensors"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "unroll" in err and "Traceback" not in err and len(err.splitlines()) == 1
