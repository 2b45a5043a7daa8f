"""strol-adaptive: λ = λ0 for the training human, shrinks when the human undoes ĝ's push,
grows when it follows it; batches, state and bad input."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from test_learners import LinearTask, constant_model

import strol_gym
from strol_gym import RobotTask
from strol_gym.learners.adaptive import AdaptiveStROLLearner
from strol_gym.learners.correction import StROLLearner
from strol_gym.tasks.highway import HighwayTask

TASK = LinearTask()
X = np.array([0.3, -0.2, 0.1])


def _learner(**kw):
    # ĝ's raw output is constant: ĝ points along +f0 (scaled to just under ‖g‖).
    return AdaptiveStROLLearner(TASK, model=constant_model(TASK, np.array([5.0, 0.0])), **kw)


def test_lambda_shrinks_when_the_human_undoes_g_hat_and_grows_when_it_follows():
    along, against = np.array([0.1, 0.0, 0.0]), np.array([-0.1, 0.0, 0.0])
    for u_next, direction in ((against, -1), (along, +1)):
        learner = _learner(reference=0.0, gain=1.0, lam_max=10.0)
        learner.update(X, np.array([0.0, 0.05, 0.0]))  # first correction: no statistic yet
        assert learner.current_lambda() == pytest.approx(1.0)
        lams = []
        for _ in range(4):
            learner.update(X, u_next)
            lams.append(float(learner.current_lambda()))
        # g ∥ −ĝ (the human undoes ĝ's push) -> λ falls; g ∥ +ĝ -> λ rises, monotonically.
        assert all(np.sign(np.diff([1.0, *lams])) == direction), lams
        assert 0.0 <= min(lams) and max(lams) <= learner.lam_max


def test_reduces_to_strol_for_the_training_human():
    model = constant_model(TASK, np.array([0.5, 2.0]))
    strol = StROLLearner(TASK, model=model)
    rng = np.random.default_rng(0)
    # λ stays λ0 while the statistic equals the reference: here gain = 0 makes every c̄ count
    # as the reference, so each update must be StROL's exactly.
    same = AdaptiveStROLLearner(TASK, model=model, gain=0.0, reference=0.3)
    for _ in range(5):
        x, u = rng.uniform(-1, 1, 3), 0.1 * rng.uniform(-1, 1, 3)
        np.testing.assert_array_equal(same.update(x, u), strol.update(x, u))
    # The shipped Robot rule calibrates c_ref on the training human; its first update is StROL's.
    task = RobotTask()
    adaptive = strol_gym.make_learner("strol-adaptive", task=task)
    assert -1.0 < adaptive.reference < 1.0
    x, u = np.array([0.3, 0.0, 0.4]), np.array([0.05, -0.02, 0.0])
    np.testing.assert_array_equal(adaptive.update(x, u), StROLLearner(task).update(x, u))


def test_batch_equals_single_and_state_round_trip():
    rng = np.random.default_rng(1)
    xs, us = rng.uniform(-1, 1, (3, 5, 3)), 0.1 * rng.uniform(-1, 1, (3, 5, 3))
    batched = _learner(reference=0.1)
    for x, u in zip(xs, us, strict=True):
        out = batched.update(x, u)
    for i in range(5):
        single = _learner(reference=0.1)
        for x, u in zip(xs, us, strict=True):
            res = single.update(x[i], u[i])
        np.testing.assert_allclose(res, out[i], atol=1e-7)
    copy = _learner(reference=0.1)
    copy.load_state_dict(batched.state_dict())
    clone = pickle.loads(pickle.dumps(batched))
    nxt = [learner.update(xs[0], us[0]) for learner in (batched, copy, clone)]
    np.testing.assert_array_equal(nxt[0], nxt[1])
    np.testing.assert_array_equal(nxt[0], nxt[2])
    batched.reset()
    assert batched.current_lambda() == pytest.approx(1.0)


def test_works_for_highway():
    task = HighwayTask()
    learner = strol_gym.make_learner("strol-adaptive", task=task)
    x = task.sample_start(np.random.default_rng(2), 2)
    out = learner.update(x, np.array([[1.0, 0.01], [-1.0, 0.0]]))
    assert out.shape == (2, 3) and np.isfinite(out).all()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"gain": -1.0}, "gain"),
        ({"gain": float("nan")}, "gain"),
        ({"lam_max": 0.5}, "lam_max"),
        ({"reference": 2.0}, "reference"),
        ({"prior_count": -1.0}, "prior_count"),
        ({"lam": -0.1}, "lam"),
    ],
)
def test_bad_arguments_name_themselves(kwargs, match):
    with pytest.raises(ValueError, match=match):
        _learner(**{"reference": 0.0, **kwargs})
