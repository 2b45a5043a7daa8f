"""Timing helpers shared by the speed scripts in benchmarks/."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

from strol_gym import checks


def env_steps_per_second(env: gym.Env, steps: int, repeats: int) -> float:
    """Best-of-``repeats`` env steps per second under fixed random actions, resets included."""
    rng = np.random.default_rng(0)
    actions = rng.uniform(
        -1, 1, size=(steps, *checks.space_shape("action_space", env.action_space))
    ).astype(np.float32)
    best = 0.0
    for r in range(repeats):
        env.reset(seed=r)
        start = time.perf_counter()
        for a in actions:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()
        best = max(best, steps / (time.perf_counter() - start))
    return best
