"""How the benchmark's robot acts in a block of episodes: a registry of robot policies.

An env preset names one (``EnvPreset.robot``). A policy maps a batch of states and the
learners' estimates θ̂ to robot actions in task units, (B, s), (B, d) -> (B, a); the runner
scales them to the action space. Built in: "task" (the Task's own ``robot_policy``) and "zeros"
(an env that drives its own robot, the action a residual on it); ``register_robot`` adds one,
a factory ``(task) -> policy`` built once per unit of work. The policies themselves live beside
``Task.robot_policy``, in ``strol_gym.tasks.policies``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from strol_gym.registry import Registry
from strol_gym.tasks.policies import MemoPolicy, Policy, ZeroPolicy

ROBOTS = Registry[Callable[[Any], Policy]](
    "robot",
    {"task": MemoPolicy, "zeros": ZeroPolicy},
    callable_as="(task) -> policy",
    hint=" naming a factory (task) -> policy",
)


def register_robot(name: str, factory: Callable[[Any], Policy] | str) -> None:
    """Make ``factory(task) -> policy`` available as ``EnvPreset(robot=name)``."""
    ROBOTS.register(name, factory)


def robot_policy(name: str, task: Any) -> Policy:
    """The policy of the robot named ``name`` (registered or "module:attr") for ``task``."""
    return ROBOTS.get(name)(task)
