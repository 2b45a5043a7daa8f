"""PPO (stable-baselines3) on the native vector Robot env, in one process.

    .venv/bin/python -m strol_gym.benchmarks.examples.sb3_vector [--envs 64] [--steps 20000]

``gymnasium.make_vec("StROL-Robot-v0", vectorization_mode="vector_entry_point")`` steps N arms
at once; ``VectorOnlineLearningWrapper`` gives each sub-env its online learner (θ̂ in
``obs["theta_hat"]``); ``strol_gym.wrappers.sb3.SB3VecEnv`` hands the batch to SB3 without
subprocesses.
Prints the mean episode return of the trained policy and of a random policy on held-out seeds.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.wrappers import VectorOnlineLearningWrapper
from strol_gym.wrappers.sb3 import SB3VecEnv


def make_vec_env(n: int, learner: str | None, **kwargs) -> SB3VecEnv:
    env = gym.make_vec("StROL-Robot-v0", n, vectorization_mode="vector_entry_point", **kwargs)
    if learner is not None:
        env = VectorOnlineLearningWrapper(env, learner, regret=False)
    return SB3VecEnv(env)


def mean_return(env: SB3VecEnv, policy, seed: int) -> float:
    """Mean return over one episode of every sub-env, seeds seed, seed + 1, ... (held out)."""
    env.seed(seed)
    obs = env.reset()
    total = np.zeros(env.num_envs)
    done = np.zeros(env.num_envs, dtype=bool)
    while not done.all():
        obs, reward, dones, _ = env.step(policy(obs))
        total += np.where(done, 0.0, reward)
        done |= dones
    return float(total.mean())


def train_and_compare(n: int, steps: int, learner: str | None, seed: int = 0, **kwargs) -> dict:
    """Train PPO for ``steps`` env steps; returns of the trained and a random policy."""
    env = make_vec_env(n, learner, **kwargs)
    model = PPO(
        "MultiInputPolicy",
        env,
        n_steps=40,
        batch_size=320,
        n_epochs=4,
        learning_rate=1e-3,
        seed=seed,
        verbose=0,
    )
    start = time.perf_counter()
    model.learn(total_timesteps=steps)
    seconds = time.perf_counter() - start
    rng = np.random.default_rng(seed)
    held_out = 1_000_000 + seed

    def trained(obs):
        return model.predict(obs, deterministic=True)[0]

    shape = checks.space_shape("action_space", env.action_space)

    def random(obs):
        return rng.uniform(-1, 1, size=(n, *shape)).astype(np.float32)

    out = {
        "trained": mean_return(env, trained, held_out),
        "random": mean_return(env, random, held_out),
        "seconds": seconds,
    }
    env.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--learner", default="gradient")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    out = train_and_compare(args.envs, args.steps, args.learner, args.seed)
    print(
        f"PPO {args.steps} steps on {args.envs} sub-envs in {out['seconds']:.1f} s; "
        f"held-out mean return: trained {out['trained']:.3f}, random {out['random']:.3f}"
    )


if __name__ == "__main__":
    main()
