"""Per-update cost of every registered learner, batch 1 and batch 256, beside Gradient's.

    .venv/bin/python lab/speed/learners.py [--env robot|highway|all] [--repeats 5]

Each figure is the best of ``--repeats`` timings of ``--updates`` consecutive updates (after one
warm-up update), in µs per update call, on one torch thread. Inputs are random admissible
corrections from the Task (seeded); the learner is reset before each timing. A learner whose
weights are not shipped for the Task is listed as skipped.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from strol_gym import RobotTask, list_learners, make_learner
from strol_gym.tasks.highway import HighwayTask

TASKS = {"robot": RobotTask, "highway": HighwayTask}


def us_per_update(learner, task, batch: int, updates: int, repeats: int) -> float:
    """Best-of-``repeats`` mean µs per ``learner.update`` on a batch of ``batch`` rows."""
    rng = np.random.default_rng(0)
    shape = (updates + 1, batch) if batch > 1 else (updates + 1,)
    x = task.sample_start(rng, int(np.prod(shape))).reshape(*shape, task.state_dim)
    u_h = task.candidate_actions(rng, int(np.prod(shape)), 1)[:, 1].reshape(*shape, -1)
    u_r = np.zeros_like(u_h)
    best = np.inf
    for _ in range(repeats):
        learner.reset()
        learner.update(x[0], u_h[0], u_r[0])  # warm-up (and the first batched copy of state)
        start = time.perf_counter()
        for i in range(1, updates + 1):
            learner.update(x[i], u_h[i], u_r[i])
        best = min(best, (time.perf_counter() - start) / updates)
    return best * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", choices=(*TASKS, "all"), default="all")
    parser.add_argument("--updates", type=int, default=20, help="timed updates per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--learners", default=",".join(list_learners()))
    args = parser.parse_args()
    torch.set_num_threads(1)
    envs = list(TASKS) if args.env == "all" else [args.env]
    for env in envs:
        task = TASKS[env]()
        rows = []
        for name in args.learners.split(","):
            try:
                learner = make_learner(name, task=task)
            except FileNotFoundError:
                print(f"{env} {name}: skipped (no shipped weights)")
                continue
            rows.append(
                (
                    name,
                    *(
                        us_per_update(learner, task, b, args.updates, args.repeats)
                        for b in (1, 256)
                    ),
                )
            )
        base = {b: t for b, t in zip((1, 256), rows[0][1:], strict=True)} if rows else {}
        print(f"\n{env}: µs per update (best of {args.repeats} × {args.updates} updates)")
        print(
            f"{'learner':16s} {'batch 1':>10s} {'× Gradient':>10s} "
            f"{'batch 256':>10s} {'× Gradient':>10s}"
        )
        for name, t1, t256 in rows:
            print(
                f"{name:16s} {t1:10.0f} {t1 / base[1]:10.1f} {t256:10.0f} {t256 / base[256]:10.1f}"
            )


if __name__ == "__main__":
    main()
