"""stable-baselines3 PPO trains on the native vector Robot env through SB3VecEnv."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch

import strol_gym  # noqa: F401
from strol_gym.wrappers.sb3 import SB3VecEnv


@pytest.fixture
def one_torch_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)  # the policy is tiny: threads only contend with the other workers
    yield
    torch.set_num_threads(before)


def test_ppo_return_rises_above_random_on_held_out_seeds(one_torch_thread):
    from strol_gym.benchmarks.examples.sb3_vector import train_and_compare

    # θ* fixed near (0.8, −0.8): reach the plate, avoid the cup. A policy can learn that from
    # the state alone within a few thousand steps; a random policy cannot.
    out = train_and_compare(16, 2560, None, prior=[[0.8, -0.8]])
    assert out["trained"] > out["random"] + 0.2, out


def test_sb3_vec_env_resets_in_the_ending_step_as_sb3_expects():
    from stable_baselines3.common.vec_env import DummyVecEnv

    vec = SB3VecEnv(gym.make_vec("StROL-Robot-v0", 3, vectorization_mode="vector_entry_point"))
    dummy = DummyVecEnv([lambda: gym.make("StROL-Robot-v0") for _ in range(3)])
    for env in (vec, dummy):
        env.seed(7)
    obs_v, obs_d = vec.reset(), dummy.reset()
    assert all(np.abs(obs_v[k] - obs_d[k]).max() < 1e-6 for k in obs_d)
    rng = np.random.default_rng(0)
    for t in range(23):
        a = rng.uniform(-1, 1, size=(3, 3)).astype(np.float32)
        obs_v, r_v, d_v, i_v = vec.step(a)
        obs_d, r_d, d_d, i_d = dummy.step(a)
        assert np.array_equal(d_v, d_d) and np.abs(r_v - r_d).max() < 1e-6
        assert all(np.abs(obs_v[k] - obs_d[k]).max() < 1e-6 for k in obs_d), t
        for iv, idd in zip(i_v, i_d, strict=True):
            assert ("terminal_observation" in iv) == ("terminal_observation" in idd)
            if "terminal_observation" in idd:
                term_v, term_d = iv["terminal_observation"], idd["terminal_observation"]
                assert all(np.abs(term_v[k] - term_d[k]).max() < 1e-6 for k in term_d)
                assert iv["TimeLimit.truncated"] == idd["TimeLimit.truncated"]
    vec.close()
    dummy.close()
