"""Env step cost in chains, a yardstick that travels between machines, from one process.

    taskset -c 1 .venv/bin/python -m strol_gym.benchmarks.speed.chains [--envs 1024]

One **chain** is one IK iteration's MuJoCo calls (``mj_kinematics`` + ``mj_comPos`` +
``mj_jacSite``) on the Robot env's own model, timed in CPU time (``time.process_time``): on a
shared core CPU time is what the process itself costs. The chain's own time drifts within a
run (by up to 2x on a machine whose other core's work slows this one), so it is timed in
bursts of ``BURST`` chains interleaved with the env steps it judges: before every burst of
500 single-env steps or every vector-env step, and after a window's last. A window's figure
is its CPU seconds per env step divided by the mean of the bursts around its steps; each env
figure is the median over ``--repeats`` windows: per single-env step, and per sub-env step of
a vector env of ``--envs`` sub-envs. Rows: StROL-Robot-v0 and StROL-Highway-v0 with the
default human and without one (``n_corrections=0``). Which kernels ran
(``STROL_GYM_KERNELS``, docs/vector.md "Speed") is printed, with the load averages, the
first env's extra cost (compiling the IK kernel), the chain's spread over the run's bursts
and the memory per sub-env (traced allocations, as ``lab/speed/vector.py``). Then each target
(``TARGETS``, chains per step, single / per sub-env at N = 1024) with its figure and whether
it is met. Pin it to one core: ``taskset -c 1``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: before numpy loads its BLAS

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402

from strol_gym.benchmarks.speed.rates import (  # noqa: E402
    ENVS,
    HUMANS,
    Window,
    env_windows,
    load,
    traced_bytes,
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


BURST = 1000
"""Chains a burst: about 3 ms, the order of one burst of env steps."""


class Yardstick:
    """Bursts of chains on the Robot env's own model; each call times one burst."""

    def __init__(self) -> None:
        self.env = gym.make("StROL-Robot-v0")
        self.env.reset(seed=0)
        robot = self.env.unwrapped
        assert isinstance(robot, RobotEnv)  # StROL-Robot-v0 is one
        self.robot = robot
        self.bursts: list[float] = []
        """CPU seconds per chain of every burst so far."""

    def __call__(self) -> float:
        """CPU seconds per chain of one burst of ``BURST`` chains."""
        ik = self.robot.ik
        m, d, site, jp, jr = ik.model, ik.data, ik.site, ik._jp, ik._jr
        kin, com, jac = mujoco.mj_kinematics, mujoco.mj_comPos, mujoco.mj_jacSite
        cpu = time.process_time()
        for _ in range(BURST):
            kin(m, d)
            com(m, d)
            jac(m, d, jp, jr, site)
        per = (time.process_time() - cpu) / BURST
        self.bursts.append(per)
        return per

    def close(self) -> None:
        self.env.close()


def chains_per_step(windows: list[Window]) -> float:
    """Median over windows of CPU seconds per step over the mean chain beside those steps."""
    return statistics.median(w.cpu / w.steps / statistics.fmean(w.beside) for w in windows)


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
    chain = Yardstick()
    many = f"N={args.envs}"
    print(
        f"{'env':18s} {'human':14s} {'single':>8s} {many:>8s}   (chains per env step;"
        f" steps per CPU second: single, {many}; each the median of {args.repeats} windows)"
    )
    envs = ENVS if args.env == "both" else (args.env,)
    figures: dict[tuple[str, str], tuple[float, float]] = {}
    for env_id in envs:
        for label, kwargs in HUMANS.items():
            one = env_windows(env_id, None, args.seconds, args.repeats, chain, **kwargs)
            vec = env_windows(env_id, args.envs, args.seconds, args.repeats, chain, **kwargs)
            figures[env_id, label] = (chains_per_step(one), chains_per_step(vec))
            rates = [statistics.median(w.steps / w.cpu for w in ws) for ws in (one, vec)]
            print(
                f"{env_id:18s} {label:14s} {figures[env_id, label][0]:8.1f}"
                f" {figures[env_id, label][1]:8.2f}   ({rates[0]:,.0f}/s, {rates[1]:,.0f}/s)"
            )
    chain.close()
    spread = sorted(chain.bursts)
    print(
        f"one chain: median {statistics.median(spread) * 1e6:.2f} µs CPU over {len(spread)}"
        f" bursts of {BURST}, from {spread[0] * 1e6:.2f} to {spread[-1] * 1e6:.2f}"
        " (each figure divides by the bursts beside its own steps)"
    )
    for env_id in envs:
        big, small = traced_bytes(env_id, args.envs), traced_bytes(env_id, 64)
        per = (big - small) / (args.envs - 64)
        print(f"{env_id:18s} memory per sub-env ≈ {per / 1024:.2f} KiB (traced numpy/Python)")
    print(f"load average after: {load()}")
    for line in target_lines(figures, args.envs):
        print(line)


if __name__ == "__main__":
    main()
