"""SHA-256 of StROL-Study-v2 rollouts: whole episodes with the default person (who pushes when
the robot is off), per Task and seed; for checking that a controller change leaves ordinary
episodes' bytes as they were.

    .venv/bin/python -m lab.study.study_v2_hashes [--seeds 3] [--steps 400]
"""

from __future__ import annotations

import argparse
import hashlib
from typing import Any

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)


def feed(h: Any, value: Any) -> None:
    """Every array and number of an observation/info tree into ``h``, keys sorted."""
    if isinstance(value, dict):
        for k in sorted(value):
            h.update(str(k).encode())
            feed(h, value[k])
    elif isinstance(value, list | tuple):
        for v in value:
            feed(h, v)
    else:
        h.update(np.asarray(value).tobytes())


def episode_hash(task: int, seed: int, steps: int, person: str | None) -> tuple[str, int, int]:
    env: Any = gym.make("StROL-Study-v2", task=task, person=person).unwrapped
    obs, info = env.reset(seed=seed)
    h = hashlib.sha256()
    feed(h, (obs, info))
    rng = np.random.default_rng(seed)
    corrections, n = 0, 0
    for _ in range(steps):
        n += 1
        a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        out = env.step(a)
        feed(h, out)
        corrections += bool(out[4].get("is_correction"))
        if out[2] or out[3]:
            break
    feed(h, env.data.qpos)
    feed(h, env.data.qvel)
    env.close()
    return h.hexdigest()[:16], n, corrections


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--steps", type=int, default=400)
    args = p.parse_args()
    for person in ("fitted", None):
        for task in (1, 2, 3):
            for seed in range(args.seeds):
                digest, n, c = episode_hash(task, seed, args.steps, person)
                print(f"person={person} task={task} seed={seed}: {digest} ({n} steps, {c} corr)")


if __name__ == "__main__":
    main()
