"""Train a stable-baselines3 PPO agent on StROL-Robot-v0 wrapped with an online learner.

    .venv/bin/python benchmarks/examples/example_sb3.py [--learner strol] [--steps 2048] [--seed 0]

The wrapper updates θ̂ from the human's corrections and puts it in ``obs["theta_hat"]``, so a
``MultiInputPolicy`` can condition on the robot's current belief. With ``--belief-reward`` the
agent is rewarded with θ̂·φ (what the robot believes), otherwise with the env's R(x, θ*). After
training, a few evaluation episodes print the learner's final error and regret.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO

from strol_gym.wrappers import OnlineLearningWrapper


def make_env(learner: str, belief_reward: bool, max_episode_steps: int) -> gym.Env:
    env = gym.make("StROL-Robot-v0", max_episode_steps=max_episode_steps)
    return OnlineLearningWrapper(env, learner, replace_reward=belief_reward)


@contextlib.contextmanager
def private_tmp() -> Iterator[None]:
    """Temporary files (stable-baselines3's logger folder ``SB3-*``, torch's compile cache
    ``torchinductor_*``) in a folder of this run's own, removed when it ends, not left in
    ``$TMPDIR``."""
    folder = tempfile.mkdtemp(prefix="strol-sb3-")
    before = tempfile.tempdir, os.environ.get("TMPDIR")
    tempfile.tempdir = os.environ["TMPDIR"] = folder
    try:
        yield
    finally:
        tempfile.tempdir = before[0]
        if before[1] is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = before[1]
        shutil.rmtree(folder, ignore_errors=True)


def main() -> None:
    with private_tmp():
        run()


def run() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--learner", default="strol")
    parser.add_argument("--steps", type=int, default=2048, help="PPO environment steps")
    parser.add_argument("--episode-steps", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--belief-reward", action="store_true")
    parser.add_argument("--eval-episodes", type=int, default=5)
    args = parser.parse_args()

    # Small MLPs on CPU: one torch thread is faster than several (and avoids oversubscription).
    torch.set_num_threads(1)
    env = make_env(args.learner, args.belief_reward, args.episode_steps)
    model = PPO("MultiInputPolicy", env, n_steps=256, batch_size=64, seed=args.seed, verbose=0)
    model.learn(total_timesteps=args.steps, progress_bar=False)

    eval_env = make_env(args.learner, args.belief_reward, args.episode_steps)
    errors, regrets, returns = [], [], []
    for episode in range(args.eval_episodes):
        obs, _ = eval_env.reset(seed=1_000_000 + episode)
        total = 0.0
        while True:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = eval_env.step(action)
            total += float(reward)
            if terminated or truncated:
                break
        errors.append(info["error"])
        regrets.append(info["regret"])
        returns.append(total)
    print(
        f"PPO on StROL-Robot-v0 + {args.learner}: {args.steps} steps; over "
        f"{args.eval_episodes} episodes: return {np.mean(returns):.3f}, "
        f"error {np.mean(errors):.3f}, regret {np.nanmean(regrets):.3f}"
    )


if __name__ == "__main__":
    main()
