"""Helpers the env test files share: seeded rollouts, deep equality, the warning allow-list."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

ALLOWED_WARNINGS = (
    # States, corrections (Gaussian noise), θ̂ (any estimate) and φ (distances) are unbounded by
    # nature, so some observation Boxes reach ±infinity.
    "A Box observation space minimum value is -infinity",
    "A Box observation space maximum value is infinity",
)


def unexpected(caught) -> list[str]:
    """The messages of recorded warnings that the allow-list does not cover."""
    return [
        str(w.message) for w in caught if not any(a in str(w.message) for a in ALLOWED_WARNINGS)
    ]


def rollout(env: gym.Env, seed: int, steps: int = 10, action_scale: float = 1.0) -> list:
    """reset(seed) then up to ``steps`` seeded random actions in ±action_scale (> 1 tests
    clipping); stops at the end of an episode."""
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    rng = np.random.default_rng(seed)
    shape = env.action_space.shape
    for _ in range(steps):
        step = env.step(rng.uniform(-action_scale, action_scale, shape).astype(np.float32))
        out.append(step)
        if step[2] or step[3]:
            break
    return out


def same(a, b) -> bool:
    """Exact equality of nested dicts / tuples / lists of arrays and numbers."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return bool(np.array_equal(a, b))
