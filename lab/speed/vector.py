"""Speed of the native vector envs beside the single envs, one process pinned to one core.

    .venv/bin/python -m lab.speed.vector [--envs 1024] [--seconds 3] [--repeats 2]

Rows, for StROL-Robot-v0 and StROL-Highway-v0, without a human (``n_corrections=0``: the
simulator and bookkeeping) and with the default human (eq. M6, 512 candidates, for the first
5 (Robot) or all 10 (Highway) steps of each 10-step episode): env steps/s of the single env
(``gymnasium.make``, resets included) and of the vector env with ``--envs`` sub-envs
(``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``, autoresets included),
and their ratio. Random actions, fixed per run. Each figure is the best of ``--repeats`` runs
of about ``--seconds`` s. Memory per sub-env: traced allocations (``tracemalloc``) of a vector
env after reset and a few steps, its size at ``--envs`` minus at 64, per extra sub-env.
Load averages are printed: the figures are noisy when other work shares the core. Rates are
given per wall-clock second and per CPU second of this process (``time.process_time``): on a
shared core the second is what the process itself costs, the first also counts its waiting.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: before numpy loads its BLAS

import argparse  # noqa: E402
import gc  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import strol_gym  # noqa: E402, F401  (registers the envs)
from strol_gym import checks  # noqa: E402

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--cpu", type=int, default=None, help="core to pin to (default: first)")
    args = parser.parse_args()
    cpus = sorted(os.sched_getaffinity(0))
    cpu = cpus[0] if args.cpu is None else args.cpu
    os.sched_setaffinity(0, {cpu})
    print(f"pinned to core {cpu}; load average before: {load()}")
    many = f"N={args.envs}"
    print(
        f"{'env steps/s':33s} {'wall-clock':^30s} | {'per CPU second':^30s}\n"
        f"{'env':18s} {'human':14s} {'single':>9s} {many:>12s} {'ratio':>7s} | "
        f"{'single':>9s} {many:>12s} {'ratio':>7s}"
    )
    for env_id in ENVS:
        for label, kwargs in HUMANS.items():
            one = single_rate(env_id, args.seconds, args.repeats, **kwargs)
            vec = vector_rate(env_id, args.envs, args.seconds, args.repeats, **kwargs)
            print(
                f"{env_id:18s} {label:14s} {one[0]:9,.0f} {vec[0]:12,.0f} {vec[0] / one[0]:6.1f}x"
                f" | {one[1]:9,.0f} {vec[1]:12,.0f} {vec[1] / one[1]:6.1f}x"
            )
    for env_id in ENVS:
        big, small = traced_bytes(env_id, args.envs), traced_bytes(env_id, 64)
        per = (big - small) / (args.envs - 64)
        print(f"{env_id:18s} memory per sub-env ≈ {per / 1024:.1f} KiB (traced numpy/Python)")
    print(f"load average after: {load()}")


if __name__ == "__main__":
    main()
