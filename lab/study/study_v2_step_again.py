"""How much of a StROL-Study-v2 control step's cost within an episode is its code and data
being fetched again: each control step of one 60 s episode (default person, StROL) run as the
episode runs it, then once more at once from the same state (simulation, controller and the
env's own fields put back; the second run must end in the same joint positions), CPU time.

    .venv/bin/python -m lab.study.study_v2_step_again [--task 2] [--seed 20100]
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import strol_gym  # noqa: E402, F401  (registers the envs)
from strol_gym import checks  # noqa: E402

FIELDS = (
    *("_time", "_touched", "_braked", "_reflex", "_n_reflex", "_brake_q", "_active"),
    "_release_at",
)
"""The env's own fields a control step may change besides the controller's state."""


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", type=int, default=2, choices=(1, 2, 3))
    p.add_argument("--seed", type=int, default=20100)
    args = p.parse_args()
    import torch

    from strol_gym.wrappers import OnlineLearningWrapper

    torch.set_num_threads(1)
    env = OnlineLearningWrapper(gym.make("StROL-Study-v2", task=args.task), "strol")
    inner: Any = env.unwrapped
    model, scratch = inner.model, mujoco.MjData(inner.model)
    simulate, clock = inner._simulate, time.process_time
    spent, steps = {"first": 0.0, "again": 0.0}, [0]

    def twice(v_sp: Any) -> None:
        if inner._rerun:
            simulate(v_sp)
            return
        mujoco.mj_copyData(scratch, model, inner.data)
        control, own = inner._control_state(), {k: getattr(inner, k) for k in FIELDS}
        segment = inner._segment.__dict__.copy()
        t0 = clock()
        simulate(v_sp)
        spent["first"] += clock() - t0
        reached = inner.data.qpos.copy()
        mujoco.mj_copyData(inner.data, model, scratch)
        inner._set_control_state(control)
        for k, v in own.items():
            setattr(inner, k, v)
        inner._segment.__dict__.update(segment)
        t0 = clock()
        simulate(v_sp)
        spent["again"] += clock() - t0
        if inner.data.qpos.tobytes() != reached.tobytes():
            raise RuntimeError("the step run again did not reach the same state")
        steps[0] += 1

    inner._simulate = twice
    zero = np.zeros(checks.space_shape("action_space", env.action_space), np.float32)
    env.reset(seed=args.seed)
    load = os.getloadavg()[0]
    truncated = False
    while not truncated:
        _, _, _, truncated, _ = env.step(zero)
    n = steps[0]
    first, again = (1e6 * spent[k] / n for k in ("first", "again"))
    print(
        f"task {args.task} seed {args.seed}: µs per control step (CPU), as the episode runs it "
        f"{first:.0f}, the same step again at once {again:.0f} ({n} steps; load average "
        f"{load:.2f} -> {os.getloadavg()[0]:.2f})"
    )
    env.close()


if __name__ == "__main__":
    main()
