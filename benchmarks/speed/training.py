"""Speed and sanity benchmark for ĝ training on the Robot task (Algorithm 1).

    .venv/bin/python benchmarks/speed/training.py [--steps 500] [--batch 100] [--runs 500]

Prints the wall time (min / median / max of ``--repeats`` runs) of a 500-step, batch-100
training run for StROL and e2e (target ≤ 5 s on 2 cores), the held-out eq. M5 term with the
trained ĝ against ĝ = 0 (Gradient), and the final error ‖θ* − θ̂‖ of a Task-level simulation
(5 corrections, eq. M6 human, paired seeds 0..runs-1, disjoint from the training seed 10 000)
for every learner at σ = 0.25, 0 and 0.5.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from strol_gym import RobotTask, make_learner
from strol_gym.learners.simulate import simulate_errors
from strol_gym.learners.training import TrainConfig, heldout_lyapunov, train_correction


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--batch", type=int, default=100)
    parser.add_argument("--seed", type=int, default=10_000)
    parser.add_argument("--runs", type=int, default=500, help="simulated humans in the check")
    parser.add_argument("--repeats", type=int, default=3, help="timed training runs per kind")
    args = parser.parse_args()

    task = RobotTask()
    models = {}
    for kind in ("strol", "e2e"):
        config = TrainConfig(kind=kind, steps=args.steps, batch=args.batch, seed=args.seed)
        walls = []
        for _ in range(max(1, args.repeats)):  # same seed: identical runs, only the time varies
            start = time.perf_counter()
            model, history = train_correction(task, config, quiet=True)
            walls.append(time.perf_counter() - start)
        check = heldout_lyapunov(task, model, config, seed=args.seed + 1)
        models[kind] = model
        print(
            f"{kind:5s} train {args.steps} steps x batch {args.batch}: wall min "
            f"{min(walls):.2f} s, median {np.median(walls):.2f} s, max {max(walls):.2f} s | "
            f"loss first10 {history['loss'][:10].mean():+.4f} last10 "
            f"{history['loss'][-10:].mean():+.4f} | held-out eq. M5 term: trained "
            f"{check['trained']:+.4f} vs ĝ=0 (Gradient) {check['gradient']:+.4f}"
        )

    learners = {name: make_learner(name, task=task) for name in ("gradient", "one", "mof")}
    learners["strol"] = make_learner("strol", task=task, model=models["strol"])
    learners["e2e"] = make_learner("e2e", task=task, model=models["e2e"])
    for sigma in (0.25, 0.0, 0.5):
        errors = simulate_errors(task, learners, n_runs=args.runs, sigma=sigma, seed=0)
        row = "  ".join(f"{k} {v.mean():.3f}±{v.std():.3f}" for k, v in errors.items())
        diff = errors["strol"] - errors["gradient"]
        print(
            f"task-level error, sigma={sigma}: {row} | StROL−Gradient {diff.mean():+.3f} "
            f"(StROL lower in {np.mean(diff < 0):.0%} of paired runs)"
        )


if __name__ == "__main__":
    main()
