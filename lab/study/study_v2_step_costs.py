"""Where a StROL-Study-v2 control step's CPU time goes: one 60 s episode (default person,
StROL), its controller's parts timed by wrappers (CPU time per call, each wrapper's own cost
included, so the parts overstate), per control step the episode took (reruns of the
counterfactual counted apart), beside bare ``mj_step`` over the same control steps from the
same states.

    .venv/bin/python -m lab.study.study_v2_step_costs [--task 2] [--seed 20100]
"""

from __future__ import annotations

import argparse
import os
import time
from collections import defaultdict
from typing import Any

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import strol_gym  # noqa: E402, F401  (registers the envs)
from strol_gym import checks  # noqa: E402
from strol_gym.compiled import use_fast  # noqa: E402

PARTS = (
    "_model_terms",
    "_admitted",
    "_step_compiled",
    "_compiled_chunk",
    "_braked_steps",
    "_note_contact",
    "_step_braked",
)
"""The controller's methods timed where the env has them (one version's code or another's)."""
KERNELS = (("step_kernel", "control_step"), ("chunk", "chunk"), ("chunk", "refresh"))
"""Compiled kernels timed as their module's attribute (called through it)."""


def arguments(doc: str) -> argparse.Namespace:
    """--task and --seed (the episode's)."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    p.add_argument("--task", type=int, default=2, choices=(1, 2, 3))
    p.add_argument("--seed", type=int, default=20100)
    return p.parse_args()


def episode_env(task: int) -> tuple[Any, Any]:
    """(StROL-Study-v2 with its default person in ``OnlineLearningWrapper`` with StROL, the
    study env itself), on one thread."""
    import torch

    from strol_gym.wrappers import OnlineLearningWrapper

    torch.set_num_threads(1)
    env = OnlineLearningWrapper(gym.make("StROL-Study-v2", task=task), "strol")
    return env, env.unwrapped


def run_episode(env: Any, seed: int) -> dict[str, Any]:
    """One episode with zero residual actions; its last info."""
    zero = np.zeros(checks.space_shape("action_space", env.action_space), np.float32)
    env.reset(seed=seed)
    truncated = False
    while not truncated:
        _, _, _, truncated, info = env.step(zero)
    return info


def main() -> None:
    args = arguments(__doc__ or "")
    import importlib

    clock = time.process_time
    spent: dict[str, float] = defaultdict(float)
    calls: dict[str, int] = defaultdict(int)

    def timed(name: str, fn: Any) -> Any:
        def run(*a: Any, **k: Any) -> Any:
            t0 = clock()
            try:
                return fn(*a, **k)
            finally:
                spent[name] += clock() - t0
                calls[name] += 1

        return run

    for module, name in KERNELS:
        try:
            mod = importlib.import_module(f"strol_gym.envs.study.{module}")
        except ImportError:
            continue
        if use_fast() and hasattr(mod, name):
            setattr(mod, name, timed(f"{module}.{name}", getattr(mod, name)))
    env, inner = episode_env(args.task)
    for name in PARTS:
        if hasattr(inner, name):
            setattr(inner, name, timed(name, getattr(inner, name)))
    simulate = inner._simulate
    paired = mujoco.MjData(inner.model)
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(inner.model, spec))

    def step(v_sp: Any) -> None:
        rerun = inner._rerun
        if not rerun:
            mujoco.mj_getState(inner.model, inner.data, state, spec)
            mujoco.mj_setState(inner.model, paired, state, spec)
            t0 = clock()
            mujoco.mj_step(inner.model, paired, nstep=inner._n_sub)
            spent["bare mj_step (paired)"] += clock() - t0
        key = "_simulate (rerun)" if rerun else "_simulate"
        t0 = clock()
        simulate(v_sp)
        spent[key] += clock() - t0
        calls[key] += 1

    inner._simulate = step
    load = os.getloadavg()[0]
    info = run_episode(env, args.seed)
    steps = calls["_simulate"]
    print(
        f"task {args.task} seed {args.seed}, compiled {use_fast()}: {steps} control steps, "
        f"{calls['_simulate (rerun)']} rerun; corrections {info['corrections']}; load average "
        f"{load:.2f} -> {os.getloadavg()[0]:.2f}"
    )
    print("µs per control step (CPU), calls:")
    for name in sorted(spent, key=lambda n: -spent[n]):
        print(f"  {name:28s} {1e6 * spent[name] / steps:8.1f}  {calls.get(name, '')}")
    ratio = (spent["bare mj_step (paired)"]) / (spent["_simulate"] + spent["_simulate (rerun)"])
    print(f"ratio_paired (the episode's physics over bare mj_step's): {ratio:.2f}")
    env.close()


if __name__ == "__main__":
    main()
