"""StROL-Study-v2's arm: does it reach where it is sent, and does it keep the cup off the objects?

    .venv/bin/python lab/study/study_v2_tracking.py [--seeds 200] [--seed 0] [--version v2]

Per Task and random study seed (no person: ``person=None``; the robot follows its plan for the
episode's random θ̂0): after a random 0.5-9 s of the plan, ``pause(2)`` holds the setpoint;
the cup's distance (m) and rotation (rad) to its setpoint after the 2 s, and whether they are
within 2 mm and 0.01 rad. Then the episode goes on to 20 s (the plan's end, the 2 s wait and
the way home): the steps on which the cup touched the pitcher, the plate or the table
(``info["contact"]``), and the steps the speed reflex fired on (no person pushes: each is a
false reflex, ``info["reflexes"]``).
"""

from __future__ import annotations

import argparse
from typing import Any

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.envs.study.geometry import rotation_error

STEPS = 400  # 20 s


def one_seed(version: str, task: int, seed: int, pause_at: float) -> tuple[float, float, int, int]:
    env: Any = gym.make(f"StROL-Study-{version}", task=task, person=None).unwrapped  # StudyEnv
    env.reset(seed=seed)
    zero = np.zeros(checks.space_shape("action_space", env.action_space), np.float32)
    touched = 0
    k = round(pause_at / 0.05)
    err = rot = float("nan")
    for i in range(STEPS):
        if i == k:
            env.pause(2.0)
        _, _, _, _, info = env.step(zero)
        touched += bool(info.get("contact", False))
        if i == k + 39:
            err = float(np.linalg.norm(env._sp[:3] - env._x[:3]))
            rot = float(np.linalg.norm(rotation_error(env._sp_R, env._site_xmat)))
    env.close()
    return err, rot, touched, int(info.get("reflexes", 0))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--version", default="v2", choices=("v1", "v2"))
    parser.add_argument("--tasks", default="1,2,3")
    args = parser.parse_args(argv)
    for task in (int(t) for t in args.tasks.split(",")):
        rng = np.random.default_rng([args.seed, task, 1])
        rows = [
            one_seed(args.version, task, int(rng.integers(20000, 30000)), rng.uniform(0.5, 9.0))
            for _ in range(args.seeds)
        ]
        err, rot, touched, reflex = (np.array(c) for c in zip(*rows, strict=True))
        ok = (err < 0.002) & (rot < 0.01)
        print(
            f"Task {task} ({args.version}, {len(rows)} seeds): after a 2 s hold within 2 mm and "
            f"0.01 rad: {ok.mean():.1%}; distance median {np.median(err) * 1000:.2f} mm, p95 "
            f"{np.percentile(err, 95) * 1000:.2f} mm, max {err.max() * 1000:.2f} mm; rotation "
            f"median {np.median(rot):.4f}, p95 {np.percentile(rot, 95):.4f}, max {rot.max():.4f} "
            f"rad; steps with the cup touching an object: {int(touched.sum())} "
            f"(seeds: {int((touched > 0).sum())}); speed reflexes {int(reflex.sum())} (seeds: "
            f"{int((reflex > 0).sum())})"
        )


if __name__ == "__main__":
    main()
