"""Does a correction model fit a study participant's corrections? The question behind which
human the study ĝ are trained on.

Runs 60 s episodes (the learner's updates, the participant's pushes, seeds outside the
study's) and, for every correction, compares its u_H as the env read it (in a_max units) with
what each human model would have corrected from the same pose and θ̂, noise-free (the mean of
8 draws): the median cosine, and u_H's largest axis beside the model's (median, in a_max). A
model whose corrections point where the participant's do is the distribution ĝ should learn.
``--env-version v2`` (default): StROL-Study-v2's fitted population against the nominal and
Boltzmann humans and v2's ĝ training human (``FittedPopulationModel``, at its intended scale);
``v1``: v1's Tasks and participant.

    python lab/study/study_fit.py --seeds 3 --env-version v2"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from typing import Any

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.humans import make_human
from strol_gym.learners.registry import make_learner
from strol_gym.tasks.study import StudyTask
from strol_gym.wrappers.online_learning import OnlineLearningWrapper, learning_env

MODELS = ("nominal", "boltzmann")
FITTED_MODEL = "strol_gym.envs.study.population:FittedPopulationModel"
"""v2's ĝ training human (compared on v2 only)."""
V1_TASK = "strol_gym.tasks.study:StudyTask{}V1"
"""v1's study Tasks (their ids find v1's ĝ; docs/study.md)."""
SEED = 930


def make_env(version: str, task: int, **kwargs: Any) -> gym.Env:
    """StROL-Study-v1 (v1's Task, which finds v1's ĝ) or StROL-Study-v2 on Task ``task``."""
    if version == "v1":
        return gym.make("StROL-Study-v1", task=V1_TASK.format(task), **kwargs)
    return gym.make("StROL-Study-v2", task=task, **kwargs)


def corrections(
    task: int, seed: int, participant: str, learner: str, version: str = "v1"
) -> list[dict]:
    """Every correction of one episode: pose, θ̂ before it, u_H."""
    env = make_env(version, task, person=participant)
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
    p.add_argument("--env-version", choices=("v1", "v2"), default="v2", help="v2 (default) or v1")
    p.add_argument(
        "--participant",
        choices=("fitted", "observer", "oracle"),
        default=None,
        help="the simulated person (default: the version's own: v2 fitted, v1 observer)",
    )
    p.add_argument("--learner", default="one", help="who learns meanwhile (one: no ĝ)")
    args = p.parse_args(argv)
    if args.seeds < 1:
        p.error(f"--seeds must be >= 1, got {args.seeds}")
    if args.participant == "fitted" and args.env_version == "v1":
        p.error("--participant fitted exists on --env-version v2 only")
    args.participant = args.participant or ("fitted" if args.env_version == "v2" else "observer")
    models = MODELS + ((FITTED_MODEL,) if args.env_version == "v2" else ())
    warnings.simplefilter("ignore", DeprecationWarning)
    print(
        f"load {os.getloadavg()[0]:.1f}; StROL-Study-{args.env_version}, participant "
        f"{args.participant}, σ = 0"
    )
    for task in (1, 2, 3):
        rows = []
        for s in range(SEED, SEED + args.seeds):
            rows += corrections(task, s, args.participant, args.learner, args.env_version)
        env = make_env(args.env_version, task, person=None)
        t = learning_env(env).task
        assert isinstance(t, StudyTask)  # both versions build one
        env.close()
        rng = np.random.default_rng(0)
        a = t.action_bound
        line = [f"Task {task}: {len(rows)} corrections, |u_H| max axis median "]
        line.append(f"{np.median([np.max(np.abs(r['u'] / a)) for r in rows]):.2f} a_max")
        for name in models:
            star = t.theta_star
            us = [model_correction(name, t, r["x"], r["theta_hat"], star, rng) for r in rows]
            cos = [cosine(r["u"] / a, u / a) for r, u in zip(rows, us, strict=True)]
            size = np.median([np.max(np.abs(u / a)) for u in us])
            label = "fitted" if name == FITTED_MODEL else name
            line.append(f"; {label}: cosine median {np.median(cos):.2f}, max axis {size:.2f}")
        print("".join(line), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
