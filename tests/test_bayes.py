"""The Bayesian learner: posterior moves toward θ*, any Task, batches, state, bad input."""

from __future__ import annotations

import dataclasses
import pickle
from typing import ClassVar

import numpy as np
import pytest

import strol_gym
from strol_gym import MixturePrior, Prior, RobotTask, Task
from strol_gym.humans import boltzmann_correction, optimal_correction
from strol_gym.learners.bayes import BayesLearner
from strol_gym.tasks.highway import HighwayTask


@dataclasses.dataclass(frozen=True, eq=False)
class FourFeatureTask(Task):
    """φ(x) = x (4 features), f = x + u_R + u_H: a stand-in for the study's 4-feature Tasks."""

    task_id: ClassVar[str] = "Test-Four-v0"
    version: ClassVar[int] = 0
    feature_names: ClassVar[tuple[str, ...]] = ("a", "b", "c", "d")
    state_dim: ClassVar[int] = 4
    action_dim: ClassVar[int] = 4

    prior: Prior = dataclasses.field(
        default_factory=lambda: MixturePrior(np.array([[1.0, 0, 0, 0.5], [0, 1.0, 0.5, 0]]))
    )
    alpha: float = 1.0

    @property
    def action_bound(self) -> np.ndarray:
        return np.full(4, 0.2)

    @property
    def prior_modes(self) -> np.ndarray:
        return np.array([[1.0, 0, 0, 0.5], [0, 1.0, 0.5, 0]])

    @property
    def feature_scale(self) -> np.ndarray:
        return np.ones(4)

    def features(self, x):
        return np.asarray(x, dtype=np.float64)

    def dynamics(self, x, u_h, u_r):
        return np.asarray(x) + u_r + u_h

    def sample_start(self, rng, n):
        return rng.uniform(-1.0, 1.0, size=(n, 4))


def _errors(task, learner, n=40, steps=5, human="nominal", seed=3):
    """Mean ‖θ* − θ̂‖ before and after ``steps`` noise-free corrections (θ* from the prior)."""
    rng = np.random.default_rng(seed)
    star = task.prior.sample(rng, n)
    x = task.sample_start(rng, n)
    u_r = np.zeros((n, task.action_dim))
    theta = np.broadcast_to(learner.reset(), (n, task.dim)).copy()
    before = np.linalg.norm(star - theta, axis=1).mean()
    learner.reset(theta)
    for _ in range(steps):
        cand = task.candidate_actions(rng, n, 128)
        if human == "nominal":
            u_h = optimal_correction(task, x, u_r, theta, star, cand)
        else:
            u_h = boltzmann_correction(task, x, u_r, star, cand, 100.0, rng)
        theta = learner.update(x, u_h, u_r)
        x = task.dynamics(x, u_h, u_r)
    return before, np.linalg.norm(star - theta, axis=1).mean()


@pytest.mark.parametrize(
    "task", [RobotTask(), HighwayTask(), FourFeatureTask()], ids=["robot", "highway", "four"]
)
@pytest.mark.parametrize(
    "likelihood, human",
    [("reward", "boltzmann"), ("teacher", "nominal")],
    ids=["reward", "teacher"],
)
def test_posterior_mean_moves_toward_theta_star(task, likelihood, human):
    learner = BayesLearner(task, n_particles=1000, likelihood=likelihood)
    before, after = _errors(task, learner, human=human)
    assert after < 0.6 * before, (before, after)


def test_registered_and_starts_at_the_modes_mean():
    for task in (RobotTask(), HighwayTask()):
        for name in ("bayes", "bayes-teacher"):
            learner = strol_gym.make_learner(name, task=task)
            np.testing.assert_allclose(learner.theta, task.prior_modes.mean(0), atol=1e-12)
    assert strol_gym.make_learner("bayes-teacher", task=RobotTask()).likelihood == "teacher"


def test_batch_rows_equal_single_runs_and_seed_reproduces():
    task = RobotTask()
    rng = np.random.default_rng(0)
    n = 4
    xs = task.sample_start(rng, 3 * n).reshape(3, n, 3)
    us = (0.1 * rng.uniform(-1, 1, (3, n, 3))).clip(-0.1, 0.1)
    batched = BayesLearner(task, n_particles=1000)
    for x, u in zip(xs, us, strict=True):
        out = batched.update(x, u)
    for i in range(n):
        single = BayesLearner(task, n_particles=1000)
        for x, u in zip(xs, us, strict=True):
            res = single.update(x[i], u[i])
        np.testing.assert_allclose(res, out[i], rtol=0, atol=1e-12)
    other = BayesLearner(task, n_particles=1000, seed=1)
    other.update(xs[0, 0], us[0, 0])
    assert not np.array_equal(
        other.theta, BayesLearner(task, n_particles=1000).update(xs[0, 0], us[0, 0])
    )


def test_resampling_keeps_particles_distinct():
    task = RobotTask()
    learner = BayesLearner(task, n_particles=1000, beta=1000.0)
    rng = np.random.default_rng(2)
    for _ in range(8):
        learner.update(task.sample_start(rng, 1)[0], np.array([0.1, -0.1, 0.0]))
    parts = learner.state_dict()["particles"].reshape(-1, task.dim)
    assert learner.state_dict()["updates"] == 8
    assert len(np.unique(parts, axis=0)) > 0.9 * len(parts)  # jittered, not collapsed
    assert np.all(parts.std(axis=0) > 0)


def test_state_dict_and_pickle_round_trip():
    task = HighwayTask()
    rng = np.random.default_rng(4)
    x = task.sample_start(rng, 3)
    u = task.candidate_actions(rng, 3, 2)[:, 1:]
    a = BayesLearner(task, n_particles=1000)
    a.update(x, u[:, 0])
    b = BayesLearner(task, n_particles=1000)
    b.load_state_dict(a.state_dict())
    c = pickle.loads(pickle.dumps(a))
    after = [learner.update(x, u[:, 1]) for learner in (a, b, c)]
    np.testing.assert_array_equal(after[0], after[1])
    np.testing.assert_array_equal(after[0], after[2])
    with pytest.raises(ValueError, match="config"):
        BayesLearner(task, n_particles=1001).load_state_dict(a.state_dict())


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"n_particles": 0}, "n_particles"),
        ({"n_particles": -5}, "n_particles"),
        ({"n_particles": 2.5}, "n_particles"),
        ({"beta": 0.0}, "beta"),
        ({"beta": -1.0}, "beta"),
        ({"beta": float("nan")}, "beta"),
        ({"beta": [1.0, float("nan")]}, "beta"),
        ({"likelihood": "greedy"}, "likelihood"),
        ({"broad_weight": 1.5}, "broad_weight"),
        ({"n_candidates": 0}, "n_candidates"),
        ({"seed": -1}, "seed"),
    ],
)
def test_bad_arguments_name_themselves(kwargs, match):
    with pytest.raises(ValueError, match=match):
        BayesLearner(RobotTask(), **kwargs)


def test_bad_input_leaves_theta_unchanged():
    learner = BayesLearner(RobotTask(), n_particles=1000)
    before = learner.state_dict()
    with pytest.raises(ValueError, match="u_h"):
        learner.update(np.array([0.3, 0.0, 0.3]), np.array([np.nan, 0.0, 0.0]))
    with pytest.raises(ValueError, match="x must have shape"):
        learner.update(np.zeros(2), np.zeros(3))
    after = learner.state_dict()
    np.testing.assert_array_equal(before["theta"], after["theta"])
    np.testing.assert_array_equal(before["particles"], after["particles"])


@pytest.mark.parametrize("key", ["particles", "beta_idx", "logw", "updates"])
def test_load_state_missing_posterior_key_names_it_and_changes_nothing(key):
    task = HighwayTask()
    rng = np.random.default_rng(5)
    x = task.sample_start(rng, 2)
    u = task.candidate_actions(rng, 2, 1)[:, 1]
    source = BayesLearner(task, n_particles=1000)
    source.update(x, u)  # θ̂ differs from a fresh learner's
    state = source.state_dict()
    del state[key]
    target = BayesLearner(task, n_particles=1000)
    before = target.state_dict()
    assert not np.array_equal(before["theta"], state["theta"])
    with pytest.raises(ValueError, match=f"missing key.*{key}"):
        target.load_state_dict(state)
    after = target.state_dict()
    np.testing.assert_array_equal(before["theta"], after["theta"])
    np.testing.assert_array_equal(before["particles"], after["particles"])
    assert after["updates"] == before["updates"]
