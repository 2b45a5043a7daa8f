"""Names -> learners. Entries are factories ``(task, **kwargs) -> learner`` or lazy "module:attr"
strings, so that importing the registry does not import torch until a learner needs it."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from strol_gym.learners.protocol import OnlineRewardLearner
from strol_gym.tasks.base import Task

Factory = Callable[..., OnlineRewardLearner]

_REGISTRY: dict[str, Factory | str] = {
    "gradient": "strol_gym.learners.rules:GradientLearner",
    "one": "strol_gym.learners.rules:OneLearner",
    "mof": "strol_gym.learners.rules:MOFLearner",
    "e2e": "strol_gym.learners.correction:E2ELearner",
    "strol": "strol_gym.learners.correction:StROLLearner",
    "bayes": "strol_gym.learners.bayes:BayesLearner",
    "bayes-teacher": "strol_gym.learners.bayes:teacher_bayes",
    "strol-adaptive": "strol_gym.learners.adaptive:AdaptiveStROLLearner",
    "strol-unrolled": "strol_gym.learners.correction:UnrolledStROLLearner",
}


def _resolve(entry: Factory | str) -> Factory:
    if isinstance(entry, str):
        module, _, attr = entry.partition(":")
        if not module or not attr:
            raise ValueError(f"a lazy learner entry must look like 'module:attr', got {entry!r}")
        return getattr(importlib.import_module(module), attr)
    return entry


def register_learner(name: str, factory: Factory | str) -> None:
    """Add a learner under ``name``. ``factory`` is called as ``factory(task=task, **kwargs)``;
    it may be a "module:attr" string, imported on first use. A name already taken is an error."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty string, got {name!r}")
    if name in _REGISTRY:
        raise ValueError(f"a learner named {name!r} is already registered")
    if isinstance(factory, str):
        if ":" not in factory:
            raise ValueError(f"a lazy factory must look like 'module:attr', got {factory!r}")
    elif not callable(factory):
        raise ValueError(f"factory must be callable or a 'module:attr' string, got {factory!r}")
    _REGISTRY[name] = factory


def unregister_learner(name: str) -> None:
    """Remove a user-registered learner (mainly for tests)."""
    if name not in _REGISTRY:
        raise ValueError(f"no learner named {name!r}; known: {', '.join(list_learners())}")
    del _REGISTRY[name]


def list_learners() -> list[str]:
    """The registered names, in registration order."""
    return list(_REGISTRY)


def make_learner(
    name: str | OnlineRewardLearner | Factory, task: Task | None = None, **kwargs: Any
) -> OnlineRewardLearner:
    """Build a learner for ``task``.

    ``name`` is a registered name ("gradient", "one", "mof", "e2e", "strol", "bayes",
    "bayes-teacher", "strol-adaptive", "strol-unrolled", or one added with
    ``register_learner``), a learner object (returned as it is; it must be built for ``task``
    when one is given), or a factory called as ``factory(task=task, **kwargs)``.
    """
    if isinstance(name, str):
        if name not in _REGISTRY:
            raise ValueError(f"unknown learner {name!r}; known learners: {', '.join(_REGISTRY)}")
        factory = _resolve(_REGISTRY[name])
    elif isinstance(name, OnlineRewardLearner) and not isinstance(name, type):
        if kwargs:
            raise ValueError(f"keyword arguments {sorted(kwargs)} cannot apply to a built learner")
        if task is not None and name.task is not task and name.task.describe() != task.describe():
            raise ValueError(
                f"the learner was built for {name.task.task_id}, not for {task.task_id}"
            )
        return name
    elif callable(name):
        factory = name
    else:
        raise ValueError(
            f"name must be a registered name, a learner or a factory, got {type(name).__name__}"
        )
    if task is None:
        raise ValueError("task is required, e.g. make_learner(name, task=env.unwrapped.task)")
    if not isinstance(task, Task):
        raise ValueError(f"task must be a strol_gym Task, got {type(task).__name__}")
    learner = factory(task=task, **kwargs)
    if not isinstance(learner, OnlineRewardLearner):
        raise ValueError(
            f"the factory for {name!r} returned {type(learner).__name__}, which lacks the "
            "OnlineRewardLearner interface (task, theta, reset, update, state_dict, "
            "load_state_dict)"
        )
    return learner
