"""stable-baselines3 end to end: PPO trains on the wrapped StROL-Robot-v0."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from strol_gym.wrappers import OnlineLearningWrapper


def test_ppo_trains_on_wrapped_robot_env():
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env

    env = OnlineLearningWrapper(gym.make("StROL-Robot-v0", max_episode_steps=16), "strol")
    check_env(env, warn=False)
    model = PPO("MultiInputPolicy", env, n_steps=128, batch_size=64, n_epochs=2, seed=0)
    model.learn(total_timesteps=256)
    obs, _ = env.reset(seed=123)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)
    _, reward, _, _, info = env.step(action)
    assert np.isfinite(reward) and np.all(np.isfinite(info["theta_hat"]))
    env.close()
