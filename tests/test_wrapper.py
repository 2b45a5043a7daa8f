"""OnlineLearningWrapper on a minimal contract env (and on StROL-Robot-v0 when present)."""

from __future__ import annotations

import pickle
from functools import partial
from typing import ClassVar

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from test_learners import LinearTask

import strol_gym
from strol_gym import NominalHuman, RobotTask
from strol_gym.learners.rules import GradientLearner
from strol_gym.wrappers import OnlineLearningWrapper
from strol_gym.wrappers.online_learning import episode_regret

CONTRACT_ID = "StROLTest-Contract-v0"


class ContractEnv(gym.Env):
    """The env contract (docs/extending.md, "Your own env") in miniature: the kinematics of
    ``task.dynamics``, an eq. M6 human for the first ``n_corrections`` steps, reward R(x', θ*)."""

    metadata: ClassVar[dict] = {"render_modes": []}

    def __init__(
        self,
        task_name: str = "linear",
        sigma: float = 0.25,
        n_corrections: int = 3,
        max_episode_steps: int = 5,
    ) -> None:
        self.task = LinearTask() if task_name == "linear" else RobotTask()
        self.sigma, self.n_corrections, self.max_steps = sigma, n_corrections, max_episode_steps
        t = self.task
        box = partial(spaces.Box, dtype=np.float32)
        self.action_space = box(-1.0, 1.0, (t.action_dim,))
        self.observation_space = spaces.Dict(
            {
                "state": box(-np.inf, np.inf, (t.state_dim,)),
                "correction": box(-np.inf, np.inf, (t.action_dim,)),
                "theta_hat": box(-np.inf, np.inf, (t.dim,)),
            }
        )
        self.theta_hat = t.prior_modes.mean(0)

    def set_theta_hat(self, theta_hat):
        self.theta_hat = np.asarray(theta_hat, dtype=np.float64).copy()

    def _obs(self, u_h):
        f = np.float32
        return {
            "state": self.x.astype(f),
            "correction": u_h.astype(f),
            "theta_hat": self.theta_hat.astype(f),
        }

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        t = self.task
        self.theta_star = t.prior.sample(self.np_random, 1)[0]
        self.x = t.sample_start(self.np_random, 1)[0]
        self.human = NominalHuman(t, self.theta_star, self.np_random, sigma=self.sigma)
        self.theta_hat, self.t = t.prior_modes.mean(0), 0
        return self._obs(np.zeros(t.action_dim)), {}

    def step(self, action):
        t = self.task
        u_r = np.clip(np.asarray(action, dtype=np.float64), -1, 1) * t.robot_action_bound
        corr = self.t < self.n_corrections
        u_h = self.human.act(self.x, u_r, self.theta_hat) if corr else np.zeros(t.action_dim)
        self.x = t.dynamics(self.x, u_h, u_r)
        self.t += 1
        phi = t.features(self.x)
        info = {
            "phi": phi,
            "correction": u_h,
            "robot_action": u_r,
            "is_correction": corr,
            "theta_star": self.theta_star.copy(),
            "theta_hat": self.theta_hat.copy(),
        }
        reward = float(phi @ self.theta_star)
        return self._obs(u_h), reward, False, self.t >= self.max_steps, info


if CONTRACT_ID not in gym.registry:
    gym.register(CONTRACT_ID, entry_point=ContractEnv)


def _episode(env, seed, action=None):
    obs, info = env.reset(seed=seed)
    while True:
        a = np.zeros(env.action_space.shape, np.float32) if action is None else action
        obs, reward, term, trunc, info = env.step(a)
        if term or trunc:
            return obs, reward, info


def test_wrapper_matches_a_direct_learner_loop():
    env = OnlineLearningWrapper(gym.make(CONTRACT_ID, sigma=0.25), "gradient")
    obs, _ = env.reset(seed=3)
    ref = GradientLearner(env.unwrapped.task)
    np.testing.assert_array_equal(obs["theta_hat"], np.float32([0.5, 0.5]))
    x = obs["state"].astype(np.float64)
    for _ in range(5):
        obs, _, term, trunc, info = env.step(np.float32([0.3, -0.2, 0.1]))
        if info["is_correction"]:
            ref.update(x, obs["correction"].astype(np.float64), info["robot_action"])
        np.testing.assert_array_equal(env.learner.theta, ref.theta)
        np.testing.assert_array_equal(obs["theta_hat"], ref.theta.astype(np.float32))
        np.testing.assert_array_equal(env.unwrapped.theta_hat, ref.theta)  # the human sees it
        x = obs["state"].astype(np.float64)
    assert trunc and not term
    assert info["error"] == pytest.approx(np.linalg.norm(info["theta_star"] - ref.theta))
    assert 0.0 <= info["cos_error"] <= 2.0
    assert np.isnan(info["regret"])  # LinearTask has no planner
    assert env.observation_space == env.env.observation_space


def test_reward_replacement_keeps_true_reward():
    env = OnlineLearningWrapper(gym.make(CONTRACT_ID), "gradient", replace_reward=True)
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.zeros(3, np.float32))
    assert reward == pytest.approx(float(info["theta_hat"] @ info["phi"]))
    assert info["true_reward"] == pytest.approx(float(info["theta_star"] @ info["phi"]))


def test_same_seed_same_episode_and_pickle():
    env = OnlineLearningWrapper(gym.make(CONTRACT_ID), "mof")
    a = _episode(env, 7)[2]
    clone = pickle.loads(pickle.dumps(env))
    b = _episode(env, 7)[2]
    c = _episode(clone, 7)[2]
    for other in (b, c):
        assert a["error"] == other["error"]
        np.testing.assert_array_equal(a["theta_hat"], other["theta_hat"])


def test_wrapper_spec_rebuilds_through_make():
    env = OnlineLearningWrapper(gym.make(CONTRACT_ID), "one")
    again = gym.make(env.spec)
    assert isinstance(again, OnlineLearningWrapper) and again.learner.name == "one"
    assert _episode(env, 1)[2]["error"] == _episode(again, 1)[2]["error"]


def test_make_vec_with_wrapper():
    venv = gym.make_vec(
        CONTRACT_ID,
        num_envs=2,
        vectorization_mode="sync",
        wrappers=[partial(OnlineLearningWrapper, learner="gradient")],
    )
    obs, _ = venv.reset(seed=[0, 1])
    assert obs["theta_hat"].shape == (2, 2)
    for _ in range(5):
        obs, _, _, trunc, info = venv.step(np.zeros((2, 3), np.float32))
    assert trunc.all() and info["_error"].all()
    singles = [
        _episode(OnlineLearningWrapper(gym.make(CONTRACT_ID), "gradient"), s)[2] for s in (0, 1)
    ]
    np.testing.assert_allclose(info["error"], [s["error"] for s in singles])
    venv.close()


def test_wrapper_rejects_foreign_envs():
    with pytest.raises(ValueError, match="strol-gym env"):
        OnlineLearningWrapper(gym.make("CartPole-v1"), "gradient")
    with pytest.raises(gym.error.ResetNeeded):
        OnlineLearningWrapper(gym.make(CONTRACT_ID), "gradient").step(np.zeros(3, np.float32))


# ------------------------------------------------------------------ the real envs


@pytest.mark.parametrize("name", ["gradient", "strol"])
def test_robot_env_through_make(name):
    env = OnlineLearningWrapper(gym.make("StROL-Robot-v0", max_episode_steps=8), name)
    obs, info = _episode(env, 0)[::2]
    assert np.isfinite(info["error"]) and np.isfinite(info["regret"])
    assert env.observation_space.contains(obs)
    np.testing.assert_allclose(obs["theta_hat"], env.learner.theta, rtol=1e-6)
    np.testing.assert_array_equal(env.unwrapped.theta_hat, env.learner.theta)  # the human's θ̂
    assert not np.array_equal(env.learner.theta, env.unwrapped.task.prior_modes.mean(0))
    env.close()


def test_regret_off_leaves_it_to_a_batched_call_with_the_same_value():
    infos, starts = [], []
    for regret in (True, False):
        env = OnlineLearningWrapper(
            gym.make("StROL-Robot-v0", max_episode_steps=5), "strol", regret=regret
        )
        infos.append(_episode(env, 3)[2])
        starts.append(env._x0)
        env.close()
    (on, off), task = infos, env.unwrapped.task
    assert "regret" not in off and off["error"] == on["error"]
    np.testing.assert_array_equal(starts[0], starts[1])
    rows = [np.stack([off[k], off[k]]) for k in ("theta_hat", "theta_star")]
    batched = episode_regret(task, *rows, np.stack([starts[1], starts[1]]))
    assert batched == [on["regret"], on["regret"]]


def test_robot_env_through_make_vec_and_pickle():
    venv = gym.make_vec(
        "StROL-Robot-v0",
        num_envs=2,
        vectorization_mode="sync",
        max_episode_steps=6,
        wrappers=[partial(OnlineLearningWrapper, learner="strol")],
    )
    venv.reset(seed=[0, 1])
    done = np.zeros(2, bool)
    for _ in range(6):
        _, _, term, trunc, info = venv.step(np.zeros((2, 3), np.float32))
        done |= term | trunc
    assert done.all() and info["_regret"].all() and np.isfinite(info["regret"]).all()
    venv.close()
    env = OnlineLearningWrapper(gym.make("StROL-Robot-v0", max_episode_steps=6), "mof")
    clone = pickle.loads(pickle.dumps(env))
    assert _episode(env, 4)[2]["error"] == _episode(clone, 4)[2]["error"]
    assert strol_gym.make_learner("gradient", task=env.unwrapped.task).task is env.unwrapped.task


def test_highway_env_through_make():
    env = OnlineLearningWrapper(gym.make("StROL-Highway-v0"), "mof")
    _, _, info = _episode(env, 0)
    assert np.isfinite(info["error"]) and np.isfinite(info["cos_error"])
    assert "regret" in info
    np.testing.assert_allclose(info["theta_hat"], env.learner.theta)
    env.close()
