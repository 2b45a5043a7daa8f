"""MOF's gate per Task: how often it accepts noise-free corrections and random actions.

``python -m lab.checks.mof_calibration`` prints, per Task, the share of
inputs whose explanation score (``MOFLearner.explanation_score``) reaches each threshold κ, for
four kinds of input at the states a run meets: the eq. M6 teacher's noise-free correction, the
same at the Task's training noise, the driver's noise-free action (Highway's paper human) and
a uniformly random admissible action, and the κ of the grid that best separates noise-free
teacher corrections from random actions (largest difference of the two accept rates).
docs/fidelity.md has the table.
"""

from __future__ import annotations

import argparse

import numpy as np

from strol_gym.humans import driver_correction, optimal_correction, perturb
from strol_gym.learners.rules import MOFLearner
from strol_gym.tasks import make_task
from strol_gym.tasks.base import Task

THRESHOLDS = (0.5, 0.7, 0.8, 0.9, 0.95, 0.98, 0.99)
TRAINING_SIGMA = {"robot": 0.25, "highway": 0.10}
"""Each paper Task's training noise (the study Tasks train at 0.25)."""


def gate_inputs(task: Task, n: int, seed: int, sigma: float) -> dict[str, tuple[np.ndarray, ...]]:
    """(x, u, u_R) batches of each input kind. θ̂ lies on the path from the prior modes' mean
    to θ* (as in training), u_R is the Task's robot policy for that θ̂."""
    rng = np.random.default_rng(seed)
    x = task.sample_start(rng, n)
    theta_star = task.prior.sample(rng, n)
    theta0 = task.prior_modes.mean(0)
    theta_hat = theta0 + rng.random((n, 1)) * (theta_star - theta0)
    u_r = task.robot_policy(x, theta_hat)
    cand = task.candidate_actions(rng, n, 512)
    u_opt = optimal_correction(task, x, u_r, theta_hat, theta_star, cand)
    u_noisy = perturb(task, u_opt, sigma, 0.0, rng)
    u_drv = driver_correction(task, x, u_r, theta_star, cand[:, :65], 4)
    u_rand = task.candidate_actions(rng, n, 1)[:, 1]
    return {
        "eq. M6, noise-free": (x, u_opt, u_r),
        f"eq. M6, σ = {sigma:g}": (x, u_noisy, u_r),
        "driver, noise-free": (x, u_drv, u_r),
        "uniformly random": (x, u_rand, u_r),
    }


def separating_threshold(clean: np.ndarray, random: np.ndarray) -> tuple[float, float]:
    """The κ in ``THRESHOLDS`` maximising accept(clean) − accept(random), and that margin."""
    margins = [float((clean >= k).mean() - (random >= k).mean()) for k in THRESHOLDS]
    i = int(np.argmax(margins))
    return THRESHOLDS[i], margins[i]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", default="robot,highway,study-task1,study-task2,study-task3")
    p.add_argument("--n", type=int, default=2000)
    p.add_argument("--seed", type=int, default=1000)
    args = p.parse_args(argv)
    print("| Task | input | " + " | ".join(f"κ = {k:g}" for k in THRESHOLDS) + " |")
    print("|---|---|" + "---|" * len(THRESHOLDS))
    for name in args.tasks.split(","):
        task = make_task(name)
        mof = MOFLearner(task, threshold=1.0)
        sigma = TRAINING_SIGMA.get(name, 0.25)
        scores = {}
        for label, (x, u, u_r) in gate_inputs(task, args.n, args.seed, sigma).items():
            scores[label] = score = mof.explanation_score(x, u, u_r)
            rates = " | ".join(f"{(score >= k).mean():.1%}" for k in THRESHOLDS)
            print(f"| {name} | {label} | {rates} |")
        kappa, margin = separating_threshold(scores["eq. M6, noise-free"], score)
        print(f"| {name} | best-separating κ: {kappa:g} (accept margin {margin:.1%}) |")


if __name__ == "__main__":
    main()
