"""The five learning rules, the registry, batching and learner state."""

from __future__ import annotations

import dataclasses
import pickle
from typing import ClassVar

import numpy as np
import pytest
import torch

import strol_gym
from strol_gym import FixedPrior, MixturePrior, Prior, RobotTask, Task
from strol_gym.learners.correction import E2ELearner, StROLLearner
from strol_gym.learners.network import SHRINK, CorrectionNet
from strol_gym.learners.registry import register_learner, unregister_learner
from strol_gym.learners.rules import GradientLearner, MOFLearner, OneLearner

NAMES = ("gradient", "one", "mof", "e2e", "strol")


@dataclasses.dataclass(frozen=True, eq=False)
class LinearTask(Task):
    """φ(x) = (x0, 2·x1); the third action axis is invisible to the features.

    f(x, u_H, u_R) = x + u_R + u_H, so g = (u_H0, 2·u_H1) by hand.
    """

    task_id: ClassVar[str] = "Test-Linear-v0"
    version: ClassVar[int] = 0
    feature_names: ClassVar[tuple[str, ...]] = ("f0", "f1")
    state_dim: ClassVar[int] = 3
    action_dim: ClassVar[int] = 3

    prior: Prior = dataclasses.field(
        default_factory=lambda: MixturePrior(np.array([[1.0, 0.0], [0.0, 1.0]]), jitter=0.1)
    )
    alpha: float = 0.5
    scale: tuple[float, float] = (1.0, 1.0)

    @property
    def action_bound(self) -> np.ndarray:
        return np.full(3, 0.1)

    @property
    def prior_modes(self) -> np.ndarray:
        return np.array([[1.0, 0.0], [0.0, 1.0]])

    @property
    def feature_scale(self) -> np.ndarray:
        return np.asarray(self.scale)

    def features(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        return np.stack([x[..., 0], 2.0 * x[..., 1]], axis=-1)

    def dynamics(self, x, u_h, u_r) -> np.ndarray:
        return np.asarray(x) + u_r + u_h

    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return rng.uniform(-1.0, 1.0, size=(n, 3))


def constant_model(task: Task, raw: np.ndarray) -> CorrectionNet:
    """A ĝ network whose raw output is the constant ``raw`` (last layer weights zero)."""
    net = CorrectionNet(task.network_input_dim, task.dim, hidden=(8,))
    with torch.no_grad():
        last = net.mlp[-1]
        last.weight.zero_()
        last.bias.copy_(torch.as_tensor(raw, dtype=torch.float32))
    return net


X = np.array([0.3, -0.2, 0.1])
ZERO = np.zeros(3)


# ------------------------------------------------------------------ hand-computed rules
def test_gradient_hand_computed():
    task = LinearTask()
    learner = GradientLearner(task)
    np.testing.assert_array_equal(learner.theta, [0.5, 0.5])  # mean of the bimodal modes
    theta = learner.update(X, np.array([0.1, -0.05, 0.07]), ZERO)
    # g = (0.1, 2·(−0.05)) = (0.1, −0.1); θ = (0.5, 0.5) + 0.5·g
    np.testing.assert_allclose(theta, [0.55, 0.45])
    np.testing.assert_allclose(learner.theta, theta)


def test_gradient_on_robot_matches_features():
    task = RobotTask()
    learner = GradientLearner(task)
    u_h, u_r = np.array([0.1, -0.1, 0.0]), np.array([0.02, 0.0, -0.01])
    x = np.array([0.2, 0.2, 0.6])
    plate, cup = task.plate, task.cup
    x_h, x_r = x + u_r + u_h, x + u_r

    def phi(p):
        return -np.array([np.linalg.norm(p[:2] - plate[:2]), np.linalg.norm(p - cup)])

    expected = np.zeros(2) + task.alpha * (phi(x_h) - phi(x_r))
    np.testing.assert_allclose(learner.update(x, u_h, u_r), expected)


def test_one_uses_feature_scale():
    # g = (0.03, 2·0.1) = (0.03, 0.2): raw argmax is feature 1, scaled by (1, 10) it is feature 0.
    u_h = np.array([0.03, 0.1, 0.0])
    plain = OneLearner(LinearTask()).update(X, u_h, ZERO)
    np.testing.assert_allclose(plain, [0.5, 0.5 + 0.5 * 0.2])
    scaled = OneLearner(LinearTask(scale=(1.0, 10.0))).update(X, u_h, ZERO)
    np.testing.assert_allclose(scaled, [0.5 + 0.5 * 0.03, 0.5])


def test_mof_ignores_unexplained_input_that_gradient_learns_from():
    task = LinearTask()
    # Mostly along the axis no feature sees: g = (0.01, 0). For w = (1, 0) the best action of
    # the same size moves x0 by ~0.1, so u_H achieves ~10 % of it: not explained.
    u_h = np.array([0.01, 0.0, 0.1])
    mof, grad = MOFLearner(task), GradientLearner(task)
    assert mof.explanation_score(X, u_h, ZERO) < 0.2
    np.testing.assert_allclose(grad.update(X, u_h, ZERO), [0.505, 0.5])
    np.testing.assert_array_equal(mof.update(X, u_h, ZERO), [0.5, 0.5])


def test_mof_and_gradient_both_learn_from_aligned_input():
    task = LinearTask()
    u_h = np.array([0.1, 0.05, 0.0])  # g = (0.1, 0.1): all effort is seen by the features
    mof, grad = MOFLearner(task), GradientLearner(task)
    assert mof.explanation_score(X, u_h, ZERO) > 0.95
    np.testing.assert_allclose(mof.update(X, u_h, ZERO), [0.55, 0.55])
    np.testing.assert_allclose(grad.update(X, u_h, ZERO), [0.55, 0.55])


def test_mof_gates_on_robot():
    task = RobotTask()
    x = np.array([0.3, 0.3, 0.5])
    # The direction that neither distance sees to first order: ⊥ both feature gradients.
    jac = task.feature_jacobian(x)
    null = np.cross(jac[0], jac[1])
    null /= np.abs(null).max()
    u_blind = 0.1 * null
    mof, grad = MOFLearner(task), GradientLearner(task)
    theta0 = mof.theta.copy()
    assert not mof.accepts(x, u_blind, ZERO)
    np.testing.assert_array_equal(mof.update(x, u_blind, ZERO), theta0)
    assert np.linalg.norm(grad.update(x, u_blind, ZERO) - theta0) > 0
    # Toward the cup: accepted, same update as Gradient.
    u_cup = 0.1 * np.sign(task.cup - x)
    grad.reset()
    assert mof.accepts(x, u_cup, ZERO)
    np.testing.assert_allclose(mof.update(x, u_cup, ZERO), grad.update(x, u_cup, ZERO))


def test_mof_rejects_no_correction_and_validates():
    task = LinearTask()
    assert MOFLearner(task).explanation_score(X, ZERO, ZERO) == 0.0
    with pytest.raises(ValueError, match="threshold"):
        MOFLearner(task, threshold=1.5)


def test_strol_and_e2e_hand_computed():
    task = LinearTask()
    raw = np.array([0.6, -0.8])  # ‖raw‖ = 1
    u_h = np.array([0.1, -0.05, 0.0])
    g = np.array([0.1, -0.1])
    g_hat = SHRINK * np.linalg.norm(g) * np.tanh(1.0) * raw  # radial squash of a unit vector
    for lam in (1.0, 0.5):
        strol = StROLLearner(task, lam=lam, model=constant_model(task, raw))
        np.testing.assert_allclose(
            strol.update(X, u_h, ZERO), 0.5 + 0.5 * (g + lam * g_hat), rtol=1e-6
        )
    e2e = E2ELearner(task, model=constant_model(task, raw))
    np.testing.assert_allclose(e2e.update(X, u_h, ZERO), 0.5 + 0.5 * g_hat, rtol=1e-6)


@pytest.mark.parametrize("task", [RobotTask(), LinearTask()], ids=["robot", "linear"])
def test_strol_with_lambda_zero_equals_gradient_exactly(task):
    rng = np.random.default_rng(3)
    model = None if isinstance(task, RobotTask) else constant_model(task, np.array([3.0, -1.0]))
    strol = StROLLearner(task, lam=0.0, model=model)
    grad = GradientLearner(task)
    x = task.sample_start(rng, 50)
    u_h = task.candidate_actions(rng, 50, 1)[:, 1]
    u_r = 0.3 * task.candidate_actions(rng, 50, 1)[:, 1]
    for _ in range(3):
        np.testing.assert_array_equal(strol.update(x, u_h, u_r), grad.update(x, u_h, u_r))


def test_strol_lam_validated():
    with pytest.raises(ValueError, match="lam"):
        StROLLearner(RobotTask(), lam=-1.0)


# ------------------------------------------------------------------ registry
def test_make_learner_all_names_with_shipped_weights():
    task = RobotTask()
    assert list(strol_gym.list_learners())[:5] == list(NAMES)
    for name in NAMES:
        learner = strol_gym.make_learner(name, task=task)
        assert isinstance(learner, strol_gym.OnlineRewardLearner)
        np.testing.assert_array_equal(learner.theta, task.prior_modes.mean(0))
        theta = learner.update(np.array([0.2, 0.2, 0.6]), np.array([0.1, -0.1, 0.0]))
        assert theta.shape == (2,) and np.isfinite(theta).all()
    assert strol_gym.make_learner("strol", task=task).checkpoint.endswith("robot_strol.safetensors")


def test_registry_errors_and_user_learners():
    task = LinearTask()
    with pytest.raises(ValueError, match="known learners: gradient, one, mof, e2e, strol"):
        strol_gym.make_learner("nope", task=task)
    with pytest.raises(ValueError, match="already registered"):
        register_learner("gradient", GradientLearner)
    with pytest.raises(ValueError, match="task is required"):
        strol_gym.make_learner("gradient")
    register_learner("test-half", lambda task, **kw: GradientLearner(task))
    register_learner("test-lazy", "strol_gym.learners.rules:OneLearner")
    try:
        assert isinstance(strol_gym.make_learner("test-half", task=task), GradientLearner)
        assert isinstance(strol_gym.make_learner("test-lazy", task=task), OneLearner)
        assert "test-lazy" in strol_gym.list_learners()
    finally:
        unregister_learner("test-half")
        unregister_learner("test-lazy")
    # Objects and factories pass straight through.
    obj = MOFLearner(task)
    assert strol_gym.make_learner(obj, task=task) is obj
    assert isinstance(strol_gym.make_learner(OneLearner, task=task), OneLearner)
    with pytest.raises(ValueError, match="lacks the OnlineRewardLearner interface"):
        strol_gym.make_learner(lambda task: object(), task=task)


def test_strol_without_shipped_weights_says_how_to_train():
    with pytest.raises(FileNotFoundError, match=r"`strol-bench train --task \S+ --kind strol"):
        strol_gym.make_learner("strol", task=LinearTask())


# ------------------------------------------------------------------ batching, validation, state
def _all_learners(task):
    model = constant_model(task, np.array([0.5, 2.0])) if isinstance(task, LinearTask) else None
    return [
        GradientLearner(task),
        OneLearner(task),
        MOFLearner(task),
        StROLLearner(task, model=model),
        E2ELearner(task, model=model),
    ]


@pytest.mark.parametrize("task", [RobotTask(), LinearTask()], ids=["robot", "linear"])
def test_batch_equals_single_samples(task):
    rng = np.random.default_rng(0)
    n = 6
    x = task.sample_start(rng, n)
    u_h = task.candidate_actions(rng, n, 1)[:, 1]
    u_r = 0.5 * task.candidate_actions(rng, n, 1)[:, 1]
    for batched, single in zip(_all_learners(task), _all_learners(task), strict=True):
        out = batched.update(x, u_h, u_r)
        assert out.shape == (n, task.dim)
        for i in range(n):
            single.reset()
            # float32 ĝ: batched matmuls may round differently from single rows
            np.testing.assert_allclose(single.update(x[i], u_h[i], u_r[i]), out[i], atol=1e-7)


def test_reset_and_input_validation():
    task = LinearTask()
    learner = GradientLearner(task)
    np.testing.assert_array_equal(learner.reset(np.array([1.0, 2.0])), [1.0, 2.0])
    np.testing.assert_array_equal(learner.reset(), [0.5, 0.5])
    assert learner.reset(np.zeros((4, 2))).shape == (4, 2)
    assert learner.update(X, np.array([0.1, 0, 0])).shape == (4, 2)  # broadcasts a sample
    with pytest.raises(ValueError, match="x must have shape"):
        learner.update(np.zeros(2), ZERO, ZERO)
    with pytest.raises(ValueError, match="finite"):
        learner.update(X, np.array([np.nan, 0, 0]), ZERO)
    with pytest.raises(ValueError, match="batch sizes"):
        learner.update(np.zeros((3, 3)), ZERO, ZERO)  # theta has B = 4
    with pytest.raises(ValueError, match="theta0"):
        learner.reset(np.zeros(3))


@pytest.mark.parametrize("name", NAMES)
def test_state_dict_and_pickle_round_trip(name):
    task = RobotTask()
    rng = np.random.default_rng(1)
    x = task.sample_start(rng, 4)
    u_h = task.candidate_actions(rng, 4, 2)[:, 1:]
    a = strol_gym.make_learner(name, task=task)
    a.update(x, u_h[:, 0], np.zeros((4, 3)))
    b = strol_gym.make_learner(name, task=task)
    b.load_state_dict(a.state_dict())
    np.testing.assert_array_equal(a.theta, b.theta)
    c = pickle.loads(pickle.dumps(a))
    np.testing.assert_array_equal(a.theta, c.theta)
    u_r = np.zeros((4, 3))
    after = [learner.update(x, u_h[:, 1], u_r) for learner in (a, b, c)]
    np.testing.assert_array_equal(after[0], after[1])
    np.testing.assert_array_equal(after[0], after[2])


def test_load_state_dict_refuses_other_learners():
    task = RobotTask()
    with pytest.raises(ValueError, match="learner 'one'"):
        GradientLearner(task).load_state_dict(OneLearner(task).state_dict())
    with pytest.raises(ValueError, match="config"):
        StROLLearner(task, lam=0.5).load_state_dict(StROLLearner(task).state_dict())
    with pytest.raises(ValueError, match="task"):
        GradientLearner(LinearTask()).load_state_dict(GradientLearner(task).state_dict())


def test_strol_state_dict_carries_weights():
    task = LinearTask()
    a = StROLLearner(task, model=constant_model(task, np.array([1.0, 0.0])))
    b = StROLLearner(task, model=constant_model(task, np.array([0.0, 1.0])))
    b.load_state_dict(a.state_dict())
    u_h = np.array([0.1, 0.02, 0.0])
    np.testing.assert_array_equal(a.update(X, u_h, ZERO), b.update(X, u_h, ZERO))


def test_fixed_prior_reset_uses_bimodal_modes_not_task_prior():
    # θ̂0 is the mean of the designer's bimodal modes even when θ* comes from another prior.
    task = RobotTask().with_prior(FixedPrior(np.array([[0.3, 0.9]])))
    np.testing.assert_array_equal(GradientLearner(task).theta, RobotTask().prior_modes.mean(0))
