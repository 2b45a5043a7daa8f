"""Env step rates of the single and the native vector envs, one process, CPU and wall-clock
time: the helpers of ``benchmarks/speed/chains.py`` and ``lab/speed/vector.py``.

Random actions, fixed per run; each figure is the best of ``repeats`` runs of about
``seconds`` s; rates per wall-clock second and per CPU second of this process
(``time.process_time``): on a shared core the second is what the process itself costs.
Memory per sub-env: traced allocations (``tracemalloc``) of a vector env after reset and a
few steps.
"""

from __future__ import annotations

import gc
import time
import tracemalloc

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks

ENVS = ("StROL-Robot-v0", "StROL-Highway-v0")
HUMANS = {"no human": {"n_corrections": 0}, "default human": {}}


def single_rate(env_id: str, seconds: float, repeats: int, **kwargs) -> tuple[float, float]:
    """Best (wall-clock, CPU-time) env steps/s of the single env."""
    env = gym.make(env_id, **kwargs)
    rng = np.random.default_rng(0)
    actions = rng.uniform(
        -1, 1, size=(500, *checks.space_shape("action_space", env.action_space))
    ).astype(np.float32)
    best = (0.0, 0.0)
    for r in range(repeats):
        env.reset(seed=r)
        n, start, cpu = 0, time.perf_counter(), time.process_time()
        while time.perf_counter() - start < seconds:
            for a in actions:
                _, _, term, trunc, _ = env.step(a)
                if term or trunc:
                    env.reset()
            n += len(actions)
        wall, used = time.perf_counter() - start, time.process_time() - cpu
        best = (max(best[0], n / wall), max(best[1], n / used))
    env.close()
    return best


def vector_rate(env_id: str, n: int, seconds: float, repeats: int, **kwargs) -> tuple[float, float]:
    """Best (wall-clock, CPU-time) env steps/s of a vector env of ``n`` sub-envs."""
    env = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kwargs)
    rng = np.random.default_rng(0)
    actions = rng.uniform(
        -1, 1, size=(20, *checks.space_shape("action_space", env.action_space))
    ).astype(np.float32)
    best = (0.0, 0.0)
    for r in range(repeats):
        env.reset(seed=1000 * r)
        k, start, cpu = 0, time.perf_counter(), time.process_time()
        while time.perf_counter() - start < seconds or k < 20:
            env.step(actions[k % 20])
            k += 1
        wall, used = time.perf_counter() - start, time.process_time() - cpu
        best = (max(best[0], k * n / wall), max(best[1], k * n / used))
    env.close()
    return best


def traced_bytes(env_id: str, n: int) -> int:
    gc.collect()
    tracemalloc.start()
    env = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    a = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
    for _ in range(3):
        env.step(a)
    gc.collect()
    size = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    env.close()
    return size


def load() -> str:
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])
