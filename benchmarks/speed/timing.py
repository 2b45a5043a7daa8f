"""Timing helpers shared by the speed scripts in benchmarks/."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np


def box_shape(space: gym.Space) -> tuple[int, ...]:
    """A Box's shape (gymnasium types ``Space.shape`` as optional: not every space has one)."""
    if space.shape is None:
        raise ValueError(f"expected a space with a shape (a Box), got {space}")
    return space.shape


def env_steps_per_second(env: gym.Env, steps: int, repeats: int) -> float:
    """Best-of-``repeats`` env steps per second under fixed random actions, resets included."""
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(steps, *box_shape(env.action_space))).astype(np.float32)
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
