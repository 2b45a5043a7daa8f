"""How the benchmark's robot acts in a block of episodes: a registry of robot policies.

An env preset names one (``EnvPreset.robot``). A policy maps a batch of states and the
learners' estimates θ̂ to robot actions in task units, (B, s), (B, d) -> (B, a); the runner
scales them to the action space. Built in: "task" (the Task's own ``robot_policy``) and "zeros"
(an env that drives its own robot, the action a residual on it); ``register_robot`` adds one,
a factory ``(task) -> policy`` built once per unit of work.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from strol_gym.registry import Registry

Policy = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""The robot's action for a batch of states and θ̂s: (B, s), (B, d) -> (B, a)."""


class MemoPolicy:
    """``task.robot_policy`` on a batch, planning each distinct row once per unit.

    The policy is a deterministic function of (x, θ̂). At step 0 every learner of a run has the
    same start state and θ̂0, so only one of them pays for that plan. Rows are compared by their
    exact bytes, and a row's plan does not depend on the rest of its batch (``Task.plan``), so
    a remembered answer is the very number a fresh call would give.
    """

    def __init__(self, task: Any) -> None:
        self.task = task
        self.cache: dict[bytes, np.ndarray] = {}

    def __call__(self, x: np.ndarray, theta: np.ndarray) -> np.ndarray:
        keys = [a.tobytes() + b.tobytes() for a, b in zip(x, theta, strict=True)]
        todo: dict[bytes, int] = {}
        for i, k in enumerate(keys):
            if k not in self.cache:
                todo.setdefault(k, i)
        if todo:
            rows = list(todo.values())
            u = np.asarray(self.task.robot_policy(x[rows], theta[rows]), dtype=np.float64)
            self.cache.update(zip(todo, u.reshape(len(rows), -1), strict=True))
        return np.stack([self.cache[k] for k in keys])


def zero_policy(x: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Action zero for every row: an env that drives its own robot (the study env's robot
    follows its plan for θ̂; the action is a residual on it) runs as the paper's robot."""
    return np.zeros_like(x)


def _zeros(task: Any) -> Policy:
    return zero_policy


ROBOTS = Registry(
    "robot",
    {"task": MemoPolicy, "zeros": _zeros},
    callable_as="(task) -> policy",
    hint=" naming a factory (task) -> policy",
)


def register_robot(name: str, factory: Callable[[Any], Policy] | str) -> None:
    """Make ``factory(task) -> policy`` available as ``EnvPreset(robot=name)``."""
    ROBOTS.register(name, factory)


def robot_policy(name: str, task: Any) -> Policy:
    """The policy of the robot named ``name`` (registered or "module:attr") for ``task``."""
    return ROBOTS.get(name)(task)
