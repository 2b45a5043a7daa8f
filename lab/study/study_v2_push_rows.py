"""Pushes in a row on StROL-Study-v2: the fastest joint, as a share of its speed limit, at
every physics step (the state each ``mj_step`` starts from, read by MuJoCo's control callback).

    .venv/bin/python -m lab.study.study_v2_push_rows [--cases 50] [--seed 0] [--task 1] [--short]

Each case: a study seed (episode) drawn in [20000, 30000), a start 1-4 s in, then ``--pushes``
pushes one after another (1 s each; ``--short``: 0.2-1 s; ``--gaps``: 0-1 s apart; force 30-41
N, torque up to 2.7 N m, random directions, through ``apply_wrench``), then 3 s without. Prints
each case's peak share, the env step after the last push where it came, and whether the speed
reflex tripped; then the largest share seen.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.envs.study.controller import VELOCITY_LIMIT


def draw(
    rng: np.random.Generator, pushes: int, short: bool = False, gaps: bool = False
) -> dict[str, Any]:
    """One case's draws."""

    def unit() -> np.ndarray:
        v = rng.normal(size=3)
        return v / np.linalg.norm(v)

    return {
        "seed": int(rng.integers(20000, 30000)),
        "start": float(rng.uniform(1.0, 4.0)),
        "wrenches": [
            (
                unit() * rng.uniform(30.0, 41.0),
                unit() * rng.uniform(0.0, 2.7),
                float(rng.uniform(0.2, 1.0)) if short else 1.0,
                float(rng.uniform(0.0, 1.0)) if gaps else 0.0,
            )
            for _ in range(pushes)
        ],
    }


def peak_share(task: int, case: dict[str, Any], after_s: float = 3.0) -> dict[str, Any]:
    """The case's largest |q̇| / limit over every physics step, where it came, and the reflex."""
    env: Any = gym.make("StROL-Study-v2", task=task, person=None).unwrapped
    env.reset(seed=case["seed"])
    zero = np.zeros(checks.space_shape("action_space", env.action_space), np.float32)
    for _ in range(round(case["start"] / 0.05)):
        env.step(zero)
    peak = {"share": 0.0, "step": -1}
    phase = {"step": 0}

    def watch(m: Any, d: Any) -> None:
        share = float(np.max(np.abs(d.qvel[:7]) / VELOCITY_LIMIT))
        if share > peak["share"]:
            peak.update(share=share, step=phase["step"])

    reflex = False
    mujoco.set_mjcb_control(watch)
    try:
        for force, torque, duration, gap in case["wrenches"]:
            env.apply_wrench(force, torque, duration=duration)
            for _ in range(max(1, round(duration / 0.05)) + round(gap / 0.05)):
                phase["step"] -= 1
                _, _, _, trunc, info = env.step(zero)
                reflex |= bool(info.get("reflex"))
        phase["step"] = 0
        for _ in range(round(after_s / 0.05)):
            phase["step"] += 1
            _, _, _, trunc, info = env.step(zero)
            reflex |= bool(info.get("reflex"))
            if trunc:
                break
    finally:
        mujoco.set_mjcb_control(None)
        env.close()
    return {"share": peak["share"], "after": peak["step"], "reflex": reflex}


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--task", type=int, default=1)
    p.add_argument("--pushes", type=int, default=4)
    p.add_argument("--short", action="store_true", help="pushes of 0.2-1 s (default 1 s)")
    p.add_argument("--gaps", action="store_true", help="0-1 s between pushes (default none)")
    args = p.parse_args(argv)
    rng = np.random.default_rng([args.seed, args.task])
    top, t0 = 0.0, time.perf_counter()
    for i in range(args.cases):
        case = draw(rng, args.pushes, args.short, args.gaps)
        r = peak_share(args.task, case)
        top = max(top, r["share"])
        print(
            f"{i:4d} seed {case['seed']} start {case['start']:.2f}: peak {r['share']:.4f}x "
            f"(env step {r['after']} after the last push) reflex {r['reflex']}  "
            f"[{time.perf_counter() - t0:.0f} s]",
            flush=True,
        )
    print(f"largest share over {args.cases} cases: {top:.4f}x")


if __name__ == "__main__":
    main()
