"""A Task-level simulation of online learning, without an env: a quick, batched check that a
learner reduces ‖θ* − θ̂‖ over a few corrections (the benchmark runs the real envs)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from strol_gym.humans import DEFAULT_CANDIDATES, human_model, teach
from strol_gym.learners.protocol import OnlineRewardLearner
from strol_gym.tasks.base import Task


def simulate_errors(
    task: Task,
    learners: Mapping[str, OnlineRewardLearner],
    n_runs: int = 100,
    n_corrections: int = 5,
    sigma: float = 0.25,
    bias: float = 0.0,
    seed: int = 0,
    n_candidates: int = DEFAULT_CANDIDATES,
    robot_policy: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    human: Any = "nominal",
    human_kwargs: dict[str, Any] | None = None,
) -> dict[str, np.ndarray]:
    """Final error ‖θ* − θ̂‖ per run for each learner, (n_runs,) each.

    Every learner sees the same θ* ~ task.prior, start states, candidate sets and noise draws
    (one Generator seeded with ``seed`` per learner: paired runs). The human is ``human`` (a
    registered name or model; default the eq. M6 teacher) with δ ~ N(ε a_max, (σ a_max)²),
    taught through the one teaching loop (``humans.teach``); θ̂ starts at the prior modes'
    mean; u_R is
    ``robot_policy(x, θ̂)`` (for example ``task.robot_policy``), or 0 when it is None; the state
    moves by ``task.dynamics(x, u_H, u_R)`` after each correction.
    """
    if n_runs < 1 or n_corrections < 0:
        raise ValueError(f"need n_runs >= 1 and n_corrections >= 0, got {n_runs}, {n_corrections}")
    model = human_model(
        human, task, sigma=sigma, bias=bias, n_candidates=n_candidates, **(human_kwargs or {})
    )
    out = {}
    for name, learner in learners.items():
        rng = np.random.default_rng(seed)
        theta_star = task.prior.sample(rng, n_runs)
        x = task.sample_start(rng, n_runs)
        theta = np.broadcast_to(learner.reset(), (n_runs, task.dim)).copy()
        learner.reset(theta)
        theta, _ = teach(
            task,
            model,
            theta_star,
            theta,
            x,
            learner.update,
            rng,
            n_corrections,
            robot_policy=robot_policy,
        )
        out[name] = np.linalg.norm(theta_star - theta, axis=-1)
    return out
