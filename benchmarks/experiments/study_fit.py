"""Does a correction model fit StROL-Study-v1's participant's corrections? The question behind
which human the study ĝ are trained on.

Runs 60 s v1 episodes (StROL learning, the participant's pushes, seeds outside the study's)
and, for every correction, compares its u_H (in a_max units) with what each human model
would have corrected from the same pose and θ̂, noise-free: the median cosine, and u_H's
largest axis beside the model's (median, in a_max). A model whose corrections point where the
participant's do is the distribution ĝ should learn.

    python benchmarks/experiments/study_fit.py --seeds 3 --participant observer
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.humans import make_human
from strol_gym.learners.registry import make_learner
from strol_gym.tasks.study import StudyTask
from strol_gym.wrappers.online_learning import OnlineLearningWrapper, learning_env

MODELS = ("nominal", "boltzmann")
V1_TASK = "strol_gym.tasks.study:StudyTask{}V1"
"""v1's study Tasks (their ids find v1's ĝ; docs/study.md)."""
SEED = 930


def corrections(task: int, seed: int, participant: str, learner: str) -> list[dict]:
    """Every correction of one episode: pose, θ̂ before it, u_H."""
    env = gym.make("StROL-Study-v1", task=V1_TASK.format(task), participant=participant, sigma=0.0)
    online = make_learner(learner, task=learning_env(env).task)
    env = OnlineLearningWrapper(env, online)
    env.reset(seed=seed)
    zero = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
    out, truncated = [], False
    theta = learning_env(env).theta_hat.copy()
    while not truncated:
        _, _, _, truncated, info = env.step(zero)
        if info["is_correction"]:
            out.append({"x": info["correction_state"], "u": info["u_h"], "theta_hat": theta})
        theta = learning_env(env).theta_hat.copy()
    env.close()
    return out


def model_correction(name: str, task, x, theta_hat, theta_star, rng) -> np.ndarray:
    """The model's noise-free correction (the mean of 8 draws for a stochastic one)."""
    human = make_human(name, task, theta_star, rng, sigma=0.0)
    zero = np.zeros(task.action_dim)
    return np.mean([human.act(x, zero, theta_hat) for _ in range(8)], axis=0)


def cosine(a: np.ndarray, b: np.ndarray) -> float:
    return float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b) + 1e-12))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=3, help="episodes per Task (3)")
    p.add_argument("--participant", choices=("observer", "oracle"), default="observer")
    p.add_argument("--learner", default="one", help="who learns meanwhile (one: no ĝ)")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore", DeprecationWarning)
    print(f"load {os.getloadavg()[0]:.1f}; participant {args.participant}, σ = 0")
    for task in (1, 2, 3):
        rows = []
        for s in range(SEED, SEED + args.seeds):
            rows += corrections(task, s, args.participant, args.learner)
        env = gym.make("StROL-Study-v1", task=V1_TASK.format(task), human=None)
        t = learning_env(env).task
        assert isinstance(t, StudyTask)  # V1_TASK names one
        env.close()
        rng = np.random.default_rng(0)
        a = t.action_bound
        line = [f"Task {task}: {len(rows)} corrections, |u_H| max axis median "]
        line.append(f"{np.median([np.max(np.abs(r['u'] / a)) for r in rows]):.2f} a_max")
        for name in MODELS:
            star = t.theta_star
            us = [model_correction(name, t, r["x"], r["theta_hat"], star, rng) for r in rows]
            cos = [cosine(r["u"] / a, u / a) for r, u in zip(rows, us, strict=True)]
            size = np.median([np.max(np.abs(u / a)) for u in us])
            line.append(f"; {name}: cosine median {np.median(cos):.2f}, max axis {size:.2f}")
        print("".join(line), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
