"""How much of a StROL-Study-v2 control step's cost within an episode is its code and data
being fetched again: each control step of one 60 s episode (default person, StROL) run as the
episode runs it, then once more at once from the same state (simulation, controller and the
env's own fields put back; the second run must end in the same joint positions), CPU time.

    .venv/bin/python -m lab.study.study_v2_step_again [--task 2] [--seed 20100]
"""

from __future__ import annotations

import os
import time
from typing import Any

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import mujoco  # noqa: E402

from lab.study.study_v2_step_costs import arguments, episode_env, run_episode  # noqa: E402

FIELDS = (
    *("_time", "_touched", "_braked", "_reflex", "_n_reflex", "_brake_q", "_active"),
    "_release_at",
)
"""The env's own fields a control step may change besides the controller's state."""


def main() -> None:
    args = arguments(__doc__ or "")
    env, inner = episode_env(args.task)
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
    load = os.getloadavg()[0]
    run_episode(env, args.seed)
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
