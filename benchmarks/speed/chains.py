"""Env step cost in chains, a yardstick that travels between machines, from one process.

    taskset -c 1 .venv/bin/python -m strol_gym.benchmarks.speed.chains [--envs 1024]

One **chain** is one IK iteration's MuJoCo calls (``mj_kinematics`` + ``mj_comPos`` +
``mj_jacSite``) on the Robot env's own model. It is timed in this process, before and after the
envs, in CPU time (``time.process_time``): on a shared core CPU time is what the process itself
costs, and a yardstick taken in the same process scales with the same core and clock. Each env
figure is CPU seconds per env step divided by CPU seconds per chain: per single-env step, and
per sub-env step of a vector env of ``--envs`` sub-envs. Rows: StROL-Robot-v0 and
StROL-Highway-v0 with the default human and without one (``n_corrections=0``). Which kernels
ran (``STROL_GYM_KERNELS``, docs/vector.md "Speed") is printed, with the load averages, the
first env's extra cost (compiling the IK kernel) and the memory per sub-env (traced allocations,
as ``lab/speed/vector.py``). Then each target (``TARGETS``, chains per step, single / per
sub-env at N = 1024) with its figure and whether it is met. Pin it to one core:
``taskset -c 1``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: before numpy loads its BLAS

import argparse  # noqa: E402
import time  # noqa: E402

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402

from strol_gym.benchmarks.speed.rates import (  # noqa: E402
    ENVS,
    HUMANS,
    load,
    single_rate,
    traced_bytes,
    vector_rate,
)
from strol_gym.compiled import kernels_in_use  # noqa: E402
from strol_gym.envs.robot.env import RobotEnv  # noqa: E402

TARGETS: dict[tuple[str, str], tuple[float, float]] = {
    ("StROL-Robot-v0", "default human"): (10.0, 3.0),
    ("StROL-Robot-v0", "no human"): (8.0, 0.8),
    ("StROL-Highway-v0", "default human"): (35.0, 9.0),
}
"""At most this many chains per env step: (single env, per sub-env at N = 1024)."""
TARGET_ENVS = 1024


def target_lines(figures: dict[tuple[str, str], tuple[float, float]], envs: int) -> list[str]:
    """One line per target: the figure measured beside it and whether it is met."""
    lines = []
    for (env_id, label), limits in TARGETS.items():
        got = figures.get((env_id, label))
        if got is None:
            continue
        for kind, limit, value in zip(("single", f"N={envs}"), limits, got, strict=True):
            if kind != "single" and envs != TARGET_ENVS:
                verdict = f"not compared (the target is at N={TARGET_ENVS})"
            else:
                verdict = "met" if value <= limit else "NOT met"
            lines.append(
                f"target {env_id} {label}, {kind}: <= {limit:g} chains; measured {value:.2f}: "
                f"{verdict}"
            )
    return lines


def chain_seconds(seconds: float, repeats: int) -> float:
    """Best CPU seconds of one chain on the Robot env's own model."""
    env = gym.make("StROL-Robot-v0")
    env.reset(seed=0)
    robot = env.unwrapped
    assert isinstance(robot, RobotEnv)  # StROL-Robot-v0 is one
    ik = robot.ik
    m, d, site, jp, jr = ik.model, ik.data, ik.site, ik._jp, ik._jr
    kin, com, jac = mujoco.mj_kinematics, mujoco.mj_comPos, mujoco.mj_jacSite
    best = float("inf")
    for _ in range(repeats):
        n, cpu = 0, time.process_time()
        while time.process_time() - cpu < seconds:
            for _ in range(1000):
                kin(m, d)
                com(m, d)
                jac(m, d, jp, jr, site)
            n += 1000
        best = min(best, (time.process_time() - cpu) / n)
    env.close()
    return best


def first_calls() -> tuple[float, float]:
    """CPU seconds of the first Robot env's build, reset and corrected step in this process
    (with the fast kernels: importing numba and loading the kernels from the disk cache, or
    compiling them when there is none), and of a second env's, which finds them loaded."""
    out = []
    for _ in range(2):
        start = time.process_time()
        env = gym.make("StROL-Robot-v0")
        env.reset(seed=0)
        env.step(env.action_space.sample())
        out.append(time.process_time() - start)
        env.close()
    return out[0], out[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--env", choices=("both", *ENVS), default="both", help="only this env's rows (default both)"
    )
    args = parser.parse_args()
    if args.envs < 65:
        parser.error("--envs must be at least 65 (memory is measured against 64 sub-envs)")
    print(f"kernels: {kernels_in_use()}; cores allowed: {sorted(os.sched_getaffinity(0))}")
    print(f"load average before: {load()}")
    first, second = first_calls()
    print(f"first Robot env build + reset + step: {first:.2f} s CPU; a second one: {second:.2f} s")
    chain = chain_seconds(args.seconds, args.repeats)
    many = f"N={args.envs}"
    print(f"one chain: {chain * 1e6:.2f} µs CPU")
    print(
        f"{'env':18s} {'human':14s} {'single':>8s} {many:>8s}   (chains per env step;"
        f" steps per CPU second: single, {many})"
    )
    envs = ENVS if args.env == "both" else (args.env,)
    figures: dict[tuple[str, str], tuple[float, float]] = {}
    for env_id in envs:
        for label, kwargs in HUMANS.items():
            one = single_rate(env_id, args.seconds, args.repeats, **kwargs)[1]
            vec = vector_rate(env_id, args.envs, args.seconds, args.repeats, **kwargs)[1]
            figures[env_id, label] = (1 / one / chain, 1 / vec / chain)
            print(
                f"{env_id:18s} {label:14s} {1 / one / chain:8.1f} {1 / vec / chain:8.2f}"
                f"   ({one:,.0f}/s, {vec:,.0f}/s)"
            )
    chain_after = chain_seconds(args.seconds, args.repeats)
    print(f"one chain, after: {chain_after * 1e6:.2f} µs CPU (the figures use the first)")
    for env_id in envs:
        big, small = traced_bytes(env_id, args.envs), traced_bytes(env_id, 64)
        per = (big - small) / (args.envs - 64)
        print(f"{env_id:18s} memory per sub-env ≈ {per / 1024:.2f} KiB (traced numpy/Python)")
    print(f"load average after: {load()}")
    for line in target_lines(figures, args.envs):
        print(line)


if __name__ == "__main__":
    main()
