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

from strol_gym.benchmarks.speed.rates import (  # noqa: E402
    ENVS,
    HUMANS,
    load,
    single_rate,
    traced_bytes,
    vector_rate,
)


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
