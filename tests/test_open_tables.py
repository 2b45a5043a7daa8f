"""Tables a user extends without editing the package: priors, ĝ kinds, the benchmark's robots
and the plots' colours."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.benchmarks.analysis.plots import PALETTE, PAPER_COLORS, learner_color
from strol_gym.benchmarks.engine.conditions import Condition, EnvPreset
from strol_gym.benchmarks.engine.robots import ROBOTS, register_robot, robot_policy
from strol_gym.learners.checkpoint import KINDS, THETA_KINDS, register_kind
from strol_gym.priors import PRIORS, FixedPrior, make_prior, register_prior


def first_mode(task_modes: np.ndarray) -> FixedPrior:
    return FixedPrior(task_modes[0])


def still_robot(task):
    return lambda x, theta: np.zeros((len(x), task.action_dim))


@pytest.fixture
def registered():
    register_prior("first-mode", first_mode)
    register_robot("still", still_robot)
    yield
    PRIORS.unregister("first-mode")
    ROBOTS.unregister("still")


def test_a_registered_prior_reaches_the_env_and_the_conditions(registered):
    env = gym.make("StROL-Robot-v0", prior="first-mode")
    modes = env.unwrapped.task.prior_modes
    for seed in range(3):
        np.testing.assert_array_equal(env.reset(seed=seed)[1]["theta_star"], modes[0])
    env.close()
    assert Condition("mine", sigma=0.1, prior="first-mode").prior == "first-mode"
    with pytest.raises(ValueError, match="unknown prior 'nope'; known priors: bimodal"):
        make_prior("nope", modes)
    with pytest.raises(ValueError, match="prior must be one of"):
        Condition("mine", sigma=0.1, prior="nope")


def test_a_registered_robot_is_an_env_preset_s_robot(registered):
    from strol_gym.tasks import RobotTask

    preset = EnvPreset("mine", "StROL-Robot-v0", 2, 2, 0.1, "regret", robot="still")
    task = RobotTask()
    u = robot_policy(preset.robot, task)(np.zeros((4, 3)), np.zeros((4, 2)))
    assert u.shape == (4, task.action_dim) and not u.any()
    with pytest.raises(ValueError, match="robot must be one of"):
        EnvPreset("mine", "StROL-Robot-v0", 2, 2, 0.1, "regret", robot="nope")


def test_a_learner_s_kind_registers_itself():
    from strol_gym.learners.correction import StROLLearner

    class Conditioned(StROLLearner):
        kind = "test-conditioned"
        sees_theta_hat = True

    try:
        assert KINDS["test-conditioned"] and "test-conditioned" in THETA_KINDS
        with pytest.raises(ValueError, match="registered with sees_theta_hat=True"):
            register_kind("test-conditioned", sees_theta_hat=False)
    finally:
        KINDS.pop("test-conditioned")
        THETA_KINDS.discard("test-conditioned")
    assert list(KINDS)[:3] == ["strol", "e2e", "strol-unrolled"]


def test_every_learner_name_has_a_colour_that_does_not_depend_on_the_others():
    assert learner_color("strol") == PAPER_COLORS["strol"]
    mine = learner_color("my_pieces:MyLearner")
    assert mine in PALETTE and mine == learner_color("my_pieces:MyLearner")
    assert len({learner_color(f"learner-{i}") for i in range(40)}) > 1


def test_the_zeros_robot_acts_in_the_action_space_not_the_state_space():
    """Robot (state 3, action 3) hid the bug; Highway (state 8, action 2) shows it."""
    from strol_gym.tasks import HighwayTask, RobotTask

    for task in (HighwayTask(), RobotTask()):
        x = task.sample_start(np.random.default_rng(0), 4)
        u = robot_policy("zeros", task)(x, np.zeros((4, len(task.prior_modes[0]))))
        assert u.shape == (4, task.action_dim)
        assert not u.any()
