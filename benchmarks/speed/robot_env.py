"""Speed of StROL-Robot-v0 (env steps/s, rendering off) and of the Robot planner (plans/s).

    .venv/bin/python benchmarks/speed/robot_env.py [--steps 20000] [--repeats 3]

Env rows, each through ``gymnasium.make`` (so with its wrappers), random actions, resets
included: the default env (eq. M6 human with 512 candidates during the first 5 of 10 steps),
the human correcting on every step, the human never correcting (arm + IK + bookkeeping only),
and the Boltzmann human. Planner rows: ``RobotTask.plan`` for one state (B=1, what a robot
policy calls each step) and for a batch of 100 (what regret evaluation calls). Each figure is
the best of ``--repeats`` timed runs, in one process on one core (threads pinned to 1; pin
the process too, ``taskset -c 0``). Target: the default env at ≥ 10,000 env steps/s on the
machine class where the code before the vector envs ran 4,352 (not met: docs/vector.md, "Speed",
compares it on this machine and counts instructions per step); planner a few ms per B=1 call.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: before numpy loads its BLAS

import argparse  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import strol_gym  # noqa: E402, F401  (registers the envs)
from strol_gym.benchmarks.speed.timing import env_steps_per_second  # noqa: E402
from strol_gym.tasks.robot import RobotTask  # noqa: E402


def robot_steps_per_second(steps: int, repeats: int, **kwargs) -> float:
    env = gym.make("StROL-Robot-v0", **kwargs)
    rate = env_steps_per_second(env, steps, repeats)
    env.close()
    return rate


def plans_per_second(batch: int, seconds: float, repeats: int) -> tuple[float, float]:
    """(plans/s, ms per call) for ``RobotTask.plan`` on ``batch`` states at once."""
    task, rng = RobotTask(), np.random.default_rng(0)
    theta, x0 = task.prior.sample(rng, batch), task.sample_start(rng, batch)
    task.plan(theta, x0)
    best = 0.0
    for _ in range(repeats):
        n, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            task.plan(theta, x0)
            n += 1
        best = max(best, n / (time.perf_counter() - start))
    return best * batch, 1e3 / best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rows: list[tuple[str, dict[str, Any]]] = [
        ("default (nominal human, 5 of 10 steps)", {}),
        ("human corrects every step", {"n_corrections": 10**9}),
        ("no human (arm + IK only)", {"n_corrections": 0}),
        ("boltzmann human", {"person": "boltzmann"}),
    ]
    print("StROL-Robot-v0, rendering off, one core")
    for name, kw in rows:
        rate = robot_steps_per_second(args.steps, args.repeats, **kw)
        print(f"  {name:42s} {rate:9,.0f} env steps/s")
    print(f"RobotTask.plan ({RobotTask().plan_steps} waypoints, projected Adam, multi-start)")
    for batch in (1, 100):
        rate, ms = plans_per_second(batch, 1.0, args.repeats)
        print(f"  B={batch:<3d} {rate:9,.0f} plans/s  ({ms:.2f} ms per call)")


if __name__ == "__main__":
    main()
