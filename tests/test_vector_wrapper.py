"""VectorOnlineLearningWrapper gives the θ̂ of N single wrapped envs (a SyncVectorEnv of them)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import SyncVectorEnv
from test_vector_envs import worst_difference

import strol_gym  # noqa: F401
from strol_gym.wrappers import OnlineLearningWrapper, VectorOnlineLearningWrapper

TOL = 1e-9


def run(env, seed: int, steps: int) -> list:
    rng = np.random.default_rng(seed)
    out = [env.reset(seed=seed)]
    for _ in range(steps):
        out.append(env.step(rng.uniform(-1, 1, size=env.action_space.shape).astype(np.float32)))
    env.close()
    return out


def pair(env_id: str, learner: str, n: int, seed: int, steps: int, env_kwargs=None, **kw):
    env_kwargs = env_kwargs or {}

    def single():
        return OnlineLearningWrapper(gym.make(env_id, **env_kwargs), learner, **kw)

    sync = run(SyncVectorEnv([single for _ in range(n)]), seed, steps)
    vec_env = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **env_kwargs)
    vec = run(VectorOnlineLearningWrapper(vec_env, learner, **kw), seed, steps)
    return sync, vec


# ĝ is a float32 torch MLP: on a batch of 3 rows it rounds differently (~1e-8) from one row at
# a time, so StROL's θ̂ agrees to float32 rounding; the numpy rules agree to double rounding.
@pytest.mark.parametrize(
    ("learner", "tol"),
    [("gradient", TOL), ("one", TOL), ("mof", TOL), ("bayes", TOL), ("strol", 1e-6)],
)
def test_vector_wrapper_theta_hat_equals_single_wrappers(learner, tol):
    sync, vec = pair("StROL-Robot-v0", learner, 3, 4, 21, regret=False, replace_reward=True)
    theta_sync = np.stack([step[-1]["theta_hat"] for step in sync])
    theta_vec = np.stack([step[-1]["theta_hat"] for step in vec])
    assert np.abs(theta_sync - theta_vec).max() < tol
    assert np.ptp(theta_vec[:, 0], axis=0).max() > 0  # θ̂ moved
    assert max(worst_difference(s, v) for s, v in zip(sync, vec, strict=True)) < tol


def test_vector_wrapper_out_of_step_sub_envs_and_regret():
    # Highway crashes end episodes at different steps: per-row resets and updates.
    kwargs = {"person": {"name": "driver", "sigma": 0.5}}
    sync, vec = pair("StROL-Highway-v0", "gradient", 8, 1, 26, env_kwargs=kwargs)
    assert sum(int(step[2].sum()) for step in vec[1:]) >= 1
    assert max(worst_difference(s, v) for s, v in zip(sync, vec, strict=True)) < TOL


def test_vector_wrapper_regret_on_robot():
    sync, vec = pair("StROL-Robot-v0", "gradient", 3, 2, 10)
    end_s, end_v = sync[-1][-1], vec[-1][-1]
    assert end_v["_regret"].all() and np.isfinite(end_v["regret"]).all()
    # the planner runs on a batch here and one episode at a time there: same to rounding
    assert np.allclose(end_s["regret"], end_v["regret"], atol=1e-6)
    assert np.abs(end_s["error"] - end_v["error"]).max() < TOL


def test_stateful_learner_refuses_out_of_step_sub_envs():
    env = gym.make_vec("StROL-Highway-v0", 2, vectorization_mode="vector_entry_point")
    wrapped = VectorOnlineLearningWrapper(env, "bayes", regret=False)
    wrapped.reset(seed=0)
    with pytest.raises(ValueError, match="reset together"):
        wrapped._reset_learners(np.array([0]), {})
