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
from collections.abc import Callable
from typing import NamedTuple

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks

ENVS = ("StROL-Robot-v0", "StROL-Highway-v0")
HUMANS = {"no human": {"n_corrections": 0}, "default human": {}}


class Window(NamedTuple):
    """One timed run of an env: env steps (sub-env steps for a vector env), wall and CPU s of
    them, and what ``between`` returned each time it ran around them."""

    steps: int
    wall: float
    cpu: float
    beside: tuple[float, ...] = ()


def env_windows(
    env_id: str,
    n: int | None,
    seconds: float,
    repeats: int,
    between: Callable[[], float] | None = None,
    **kwargs,
) -> list[Window]:
    """``repeats`` windows of about ``seconds`` s of the single env (``n`` None: bursts of 500
    steps, resets included) or of a vector env of ``n`` sub-envs (one step a call, at least 20),
    reset with seed r (single) or 1000 r (vector) before window r. ``between`` runs before
    each call and after a window's last, its results kept in ``Window.beside``; its time is
    not the env's (``chains.py`` times its yardstick there, interleaved with the steps it
    judges)."""
    env: gym.Env | gym.vector.VectorEnv
    if n is None:
        env = gym.make(env_id, **kwargs)
        batch, seed_step, min_calls = 500, 1, 1
    else:
        env = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kwargs)
        batch, seed_step, min_calls = 20, 1000, 20
    space = env.action_space
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(batch, *checks.space_shape("action_space", space)))
    actions = actions.astype(np.float32)

    def single_burst(_: int) -> int:
        for a in actions:
            _obs, _r, term, trunc, _info = env.step(a)
            if term or trunc:
                env.reset()
        return batch

    def vector_step(k: int) -> int:
        env.step(actions[k % batch])
        return n or 0

    call = single_burst if n is None else vector_step
    windows = []
    for r in range(repeats):
        env.reset(seed=seed_step * r)
        windows.append(_timed(call, seconds, min_calls, between))
    env.close()
    return windows


def _timed(
    call: Callable[[int], int], seconds: float, min_calls: int, between: Callable[[], float] | None
) -> Window:
    """Calls ``call(k)``, k = 0, 1, ..., for ``seconds`` wall-clock s and at least
    ``min_calls`` times; sums the steps it returns and the time inside it."""
    steps, wall, cpu, k = 0, 0.0, 0.0, 0
    beside: list[float] = []
    end = time.perf_counter() + seconds
    while k < min_calls or time.perf_counter() < end:
        if between is not None:
            beside.append(between())
        w, c = time.perf_counter(), time.process_time()
        steps += call(k)
        wall += time.perf_counter() - w
        cpu += time.process_time() - c
        k += 1
    if between is not None:
        beside.append(between())
    return Window(steps, wall, cpu, tuple(beside))


def best_rate(windows: list[Window]) -> tuple[float, float]:
    """Best (wall-clock, CPU-time) steps/s over the windows."""
    return max(w.steps / w.wall for w in windows), max(w.steps / w.cpu for w in windows)


def single_rate(env_id: str, seconds: float, repeats: int, **kwargs) -> tuple[float, float]:
    """Best (wall-clock, CPU-time) env steps/s of the single env."""
    return best_rate(env_windows(env_id, None, seconds, repeats, **kwargs))


def vector_rate(env_id: str, n: int, seconds: float, repeats: int, **kwargs) -> tuple[float, float]:
    """Best (wall-clock, CPU-time) env steps/s of a vector env of ``n`` sub-envs."""
    return best_rate(env_windows(env_id, n, seconds, repeats, **kwargs))


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
