"""strol-gym: Gymnasium envs, online reward learners and benchmarks for StROL (RA-L 2024).

Importing the package registers ``StROL-Robot-v0``, ``StROL-Highway-v0`` and
``StROL-Study-v0``, ``-v1`` and ``-v2`` (strol_gym.registration; the envs live in
strol_gym.envs, one subpackage per simulator).
"""

from __future__ import annotations

from typing import Any

from strol_gym.humans import BoltzmannHuman, Human, NominalHuman, register_human
from strol_gym.priors import FixedPrior, MixturePrior, Prior, UniformPrior
from strol_gym.registration import register_envs
from strol_gym.tasks import HighwayTask, RobotTask, Task, make_task, register_task

__version__ = "0.1.0"

register_envs()

# Learner-facing names live in strol_gym.learners (torch is imported only when asked for).
_LAZY = {
    "make_learner": "strol_gym.learners.registry",
    "register_learner": "strol_gym.learners.registry",
    "list_learners": "strol_gym.learners.registry",
    "OnlineRewardLearner": "strol_gym.learners.protocol",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'strol_gym' has no attribute {name!r}")


__all__ = [
    "BoltzmannHuman",
    "FixedPrior",
    "HighwayTask",
    "Human",
    "MixturePrior",
    "NominalHuman",
    "OnlineRewardLearner",
    "Prior",
    "RobotTask",
    "Task",
    "UniformPrior",
    "__version__",
    "list_learners",
    "make_learner",
    "make_task",
    "register_human",
    "register_learner",
    "register_task",
]
