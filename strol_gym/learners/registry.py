"""Names -> learners. Entries are factories ``(task, **kwargs) -> learner`` or lazy "module:attr"
strings, so that importing the registry does not import torch until a learner needs it.

``LEARNERS`` is this table's :class:`strol_gym.registry.Registry`: anywhere a learner name is
accepted, a ``"module:attr"`` naming a factory, a class or a learner object is accepted too.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from strol_gym.learners.protocol import OnlineRewardLearner
from strol_gym.registry import Registry
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
    "e2e-scratch": "strol_gym.learners.correction:E2EScratchLearner",
}

_DISPLAY: dict[str, str] = {
    "gradient": "Gradient",
    "one": "One",
    "mof": "MOF",
    "e2e": "e2e",
    "strol": "StROL",
}
"""How tables spell the built-in learners (the paper's spelling); others keep their name."""


def _check_factory(name: str, factory: Any) -> None:
    if not callable(factory) and not isinstance(factory, OnlineRewardLearner):
        raise ValueError(f"factory must be callable or a 'module:attr' string, got {factory!r}")


LEARNERS = Registry(
    "learner",
    _REGISTRY,
    check=_check_factory,
    hint=" naming a learner factory, class or object",
)


def register_learner(name: str, factory: Factory | str, *, display: str | None = None) -> None:
    """Add a learner under ``name``. ``factory`` is called as ``factory(task=task, **kwargs)``;
    it may be a "module:attr" string, imported on first use. A name already taken is an error.
    ``display`` is how result tables spell it (default: ``name``)."""
    LEARNERS.register(name, factory)
    if display is not None:
        _DISPLAY[name] = str(display)


def unregister_learner(name: str) -> None:
    """Remove a user-registered learner (mainly for tests)."""
    LEARNERS.unregister(name)
    if name not in LEARNERS.builtin:
        _DISPLAY.pop(name, None)


def list_learners() -> list[str]:
    """The registered names, in registration order."""
    return LEARNERS.names()


def display_name(name: str) -> str:
    """How tables spell learner ``name``."""
    return _DISPLAY.get(name, name)


def make_learner(
    name: str | OnlineRewardLearner | Factory, task: Task | None = None, **kwargs: Any
) -> OnlineRewardLearner:
    """Build a learner for ``task``.

    ``name`` is a registered name (``list_learners()``), a ``"module:attr"`` naming a factory,
    class or learner object, a learner object (returned as it is; it must be built for
    ``task`` when one is given), or a factory called as ``factory(task=task, **kwargs)``.
    """
    label = name
    if isinstance(name, str):
        name = LEARNERS.get(name)
    if isinstance(name, OnlineRewardLearner) and not isinstance(name, type):
        if kwargs:
            raise ValueError(f"keyword arguments {sorted(kwargs)} cannot apply to a built learner")
        if task is not None and name.task is not task and name.task.describe() != task.describe():
            raise ValueError(
                f"the learner was built for {name.task.task_id}, not for {task.task_id}"
            )
        return name
    if not callable(name):
        raise ValueError(
            f"name must be a registered name, a learner or a factory, got {type(name).__name__}"
        )
    if task is None:
        raise ValueError("task is required, e.g. make_learner(name, task=env.unwrapped.task)")
    if not isinstance(task, Task):
        raise ValueError(f"task must be a strol_gym Task, got {type(task).__name__}")
    try:
        learner = name(task=task, **kwargs)
    except (ValueError, OSError):  # already say what is wrong (OSError: a missing checkpoint)
        raise
    except Exception as e:  # a user's factory may raise anything: name it, no traceback
        raise ValueError(f"learner {label!r} failed to build: {type(e).__name__}: {e}") from e
    if not isinstance(learner, OnlineRewardLearner):
        raise ValueError(
            f"the factory for {label!r} returned {type(learner).__name__}, which lacks the "
            "OnlineRewardLearner interface (task, theta, reset, update, state_dict, "
            "load_state_dict)"
        )
    return learner
