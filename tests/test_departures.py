"""The paper-fidelity pieces of issue 34: e2e from scratch (unbounded ĝ), the Highway preset's
driver, the labelled teacher variant, MOF's gate table and the x_R Task variant."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
import torch

from lab.checks.departures import RobotTaskXR, robot_alpha1
from lab.checks.mof_calibration import separating_threshold
from strol_gym.benchmarks.engine.conditions import (
    PAPER_LEARNERS,
    PAPER_TABLE_LEARNERS,
    paper_condition,
)
from strol_gym.benchmarks.engine.config import paper_config
from strol_gym.benchmarks.experiments.paper import Paper
from strol_gym.learners.network import CorrectionNet, bound_correction
from strol_gym.learners.registry import make_learner
from strol_gym.learners.training import TrainConfig
from strol_gym.tasks import make_task
from strol_gym.tasks.robot import RobotTask


def test_bound_none_returns_the_raw_output():
    raw = torch.tensor([[3.0, -4.0]])
    g = torch.tensor([[1e-3, 0.0]], dtype=torch.float64)
    out = bound_correction(raw, g, "none")
    assert out.dtype == torch.float64
    np.testing.assert_array_equal(out.numpy(), [[3.0, -4.0]])
    assert torch.linalg.vector_norm(bound_correction(raw, g, "radial")) < 1e-3


@pytest.mark.parametrize("task_name", ["robot", "highway"])
def test_shipped_e2e_scratch_is_unbounded(task_name):
    """e2e-scratch loads its shipped ĝ (bound "none"): where g = 0 (no correction) its step
    need not vanish, which the bounded e2e's must."""
    task = make_task(task_name)
    scratch = make_learner("e2e-scratch", task=task)
    bounded = make_learner("e2e", task=task)
    assert scratch.model.bound == "none" and bounded.model.bound == "radial"
    x = task.sample_start(np.random.default_rng(0), 16)
    zero = np.zeros((16, task.action_dim))
    g_hat = scratch.correction(x, zero, zero)
    assert np.linalg.norm(g_hat, axis=1).max() > 0
    np.testing.assert_array_equal(bounded.correction(x, zero, zero), 0.0)


def test_e2e_scratch_needs_the_unbounded_network():
    with pytest.raises(ValueError, match="bound must be 'none' for kind 'e2e-scratch'"):
        TrainConfig(kind="e2e-scratch", bound="radial")
    with pytest.raises(ValueError, match="for kind 'e2e'"):
        TrainConfig(kind="e2e", bound="none")
    assert TrainConfig(kind="e2e-scratch", bound="none").bound == "none"
    assert CorrectionNet(3, 2, (8,), "none").arch()["bound"] == "none"


def test_paper_preset_highway_conditions_use_the_driver():
    for name in ("training", "clean", "noisy-biased", "uniform-prior"):
        assert paper_condition("highway", name).human == "driver"
        assert paper_condition("robot", name).human is None  # the env's eq. M6 teacher
    cfg = paper_config(["highway"], runs=2)
    assert cfg.learners == PAPER_TABLE_LEARNERS and cfg.is_paper()
    assert set(PAPER_TABLE_LEARNERS) - set(PAPER_LEARNERS) == {"e2e-scratch"}
    teacher = paper_config(["highway"], runs=2, human="nominal")
    assert {e.condition.human for e in teacher.experiments} == {"nominal"}
    assert not teacher.is_paper()  # a labelled variant: no H1/H2 verdict


def test_paper_human_option_names_its_folder_and_checks_the_name():
    p = argparse.ArgumentParser()
    Paper().add_arguments(p)
    args = p.parse_args(["--env", "highway", "--human", "nominal"])
    assert Paper().default_out(args) == "results/paper-highway-human-nominal"
    with pytest.raises(ValueError, match="nobody"):
        Paper().plan(p.parse_args(["--env", "highway", "--human", "nobody"]))


def test_separating_threshold_picks_the_widest_accept_margin():
    clean = np.array([0.99, 0.97, 0.96, 0.2])
    random = np.array([0.85, 0.6, 0.95, 0.1])
    kappa, margin = separating_threshold(clean, random)
    assert kappa == 0.9 and margin == pytest.approx(0.5)


def test_xr_variant_feeds_g_hat_the_state_g_is_evaluated_at():
    task, base = RobotTaskXR(), RobotTask()
    rng = np.random.default_rng(0)
    x = task.sample_start(rng, 5)
    u_h, u_r = (rng.uniform(-0.1, 0.1, (5, 3)) for _ in range(2))
    x_r = base.dynamics(x, np.zeros_like(u_h), u_r)
    np.testing.assert_array_equal(
        task.network_input(x, u_h, u_r), base.network_input(x_r, u_h, u_r)
    )
    assert task.task_id != base.task_id and robot_alpha1().alpha == 1.0
