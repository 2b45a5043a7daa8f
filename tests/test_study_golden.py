"""Golden rollouts of StROL-Study-v0, -v1 and -v2: one short episode per Task with no simulated
person (``person=None``), one scripted push and the Gradient learner, hashed. Neither ĝ nor the
fitted population takes part, so retraining one or refitting the other does not move them; a
change to the arm, its controller, the scene, u_H's reading or a Task's planner does.

Recorded once; regenerate (after a change meant to move them) with

    .venv/bin/python tests/test_study_golden.py

and say in the commit why they moved.
"""

from __future__ import annotations

import hashlib

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.learners.registry import make_learner
from strol_gym.wrappers import OnlineLearningWrapper
from strol_gym.wrappers.online_learning import learning_env

SEED = 20000
BEFORE, PUSHED, AFTER = 10, 20, 10
"""Control steps (0.05 s each) before the push, while it lasts (1 s) and after it."""

GOLDEN = {
    # recorded at the commit the package's redesign started from (f8ad26c) and after it
    "v0-task1": "171edd9e16cb0f62",
    "v0-task2": "a025c1c7c13039a3",
    "v0-task3": "4fa95467bb9729fa",
    "v1-task1": "91248d5a8a378203",
    "v1-task2": "0f5c2e68edbb937d",
    "v1-task3": "489ba07700b22c15",
    "v2-task1": "3b4cf5c5e0bd9dc0",
    "v2-task2": "d57dff54392175ac",
    "v2-task3": "c7be05b26288ae57",
}


def rollout(version: str, task: int) -> str:
    """The episode's hash: every step's state, reward, u_H and flags, and the learner's θ̂,
    rounded to 1e-9 (bytes below that are the machine's, not the model's)."""
    env = gym.make(f"StROL-Study-{version}", task=task, person=None)
    learner = make_learner("gradient", task=learning_env(env).task)
    wrapped = OnlineLearningWrapper(env, learner)
    h = hashlib.sha256()

    def add(*arrays: object) -> None:
        for a in arrays:
            h.update(np.round(np.asarray(a, dtype=np.float64), 9).tobytes())

    obs, _ = wrapped.reset(seed=SEED)
    add(obs["state"], learner.theta)
    zero = np.zeros(wrapped.action_space.shape, np.float32)
    torque = [0.0, 0.0, 0.0] if task == 1 else [0.0, 2.0, 0.0]
    for step in range(BEFORE + PUSHED + AFTER):
        if step == BEFORE:
            learning_env(env).apply_wrench([0.0, 30.0, 0.0], torque, duration=PUSHED * 0.05)
        obs, reward, term, trunc, info = wrapped.step(zero)
        add(obs["state"], reward, info["u_h"], learner.theta)
        h.update(bytes([bool(info["is_correction"]), term, trunc]))
    wrapped.close()
    return h.hexdigest()[:16]


CASES = [(v, t) for v in ("v0", "v1", "v2") for t in (1, 2, 3)]


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize(("version", "task"), CASES)
def test_a_study_rollout_equals_its_recording(version, task):
    assert rollout(version, task) == GOLDEN[f"{version}-task{task}"]


if __name__ == "__main__":
    import warnings

    warnings.simplefilter("ignore", DeprecationWarning)
    for v, t in CASES:
        print(f'    "{v}-task{t}": "{rollout(v, t)}",')
