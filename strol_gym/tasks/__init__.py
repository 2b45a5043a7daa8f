"""Settings (Tasks): φ, g, prior, action bound, start distribution and planner.

``TASKS`` names the Tasks (``register_task`` adds one); ``make_task`` builds one from a name,
an env id (a Task's ``task_id``), a ``"module:attr"`` or a Task object.
"""

from collections.abc import Callable
from typing import Any, TypeVar, overload

from strol_gym.registry import Registry, call_piece
from strol_gym.tasks.base import Task
from strol_gym.tasks.highway import HighwayTask
from strol_gym.tasks.robot import RobotTask
from strol_gym.tasks.study import STUDY_TASK_SETS, study_task_name

_TASKS: dict[str, Any] = {
    "robot": "strol_gym.tasks.robot:RobotTask",
    "highway": "strol_gym.tasks.highway:HighwayTask",
    **{
        study_task_name(version, number): f"{cls.__module__}:{cls.__qualname__}"
        for version, tasks in STUDY_TASK_SETS.items()
        for number, cls in tasks.items()
    },
}


def _check(name: str, task: Any) -> None:
    if not isinstance(task, Task) and not callable(task):
        raise ValueError(
            f"task {name!r} must be a Task, a Task class, a factory () -> Task or 'module:attr', "
            f"got {task!r}"
        )


TASKS = Registry[Task | Callable[[], Task]](
    "task", _TASKS, check=_check, hint=" naming a Task, Task class or factory"
)


def register_task(name: str, task: Any) -> None:
    """Make ``task`` (a Task, a Task class or a factory ``() -> Task``, or its "module:attr")
    available by ``name``: ``gym.make(..., task=name)``, ``strol-bench run --task``, training."""
    TASKS.register(name, task)


TaskT = TypeVar("TaskT", bound=Task)


@overload
def make_task(spec: Any, of: None = None) -> Task: ...
@overload
def make_task(spec: Any, of: type[TaskT]) -> TaskT: ...
def make_task(spec: Any, of: type[Task] | None = None) -> Task:
    """The Task for ``spec``: a Task, a registered name, an env id (a Task's ``task_id``) or a
    ``"module:attr"`` naming a Task, a Task class or a factory. ``of``: the class it must be."""
    if isinstance(spec, str):
        if spec not in TASKS and ":" not in spec:
            by_id = {}
            for name in TASKS.names():
                entry = TASKS.get(name)
                task_id = getattr(entry, "task_id", None)
                if isinstance(task_id, str):
                    by_id[task_id] = name
            spec = by_id.get(spec, spec)
        obj = TASKS.get(spec)
    else:
        obj = spec
    task = obj if isinstance(obj, Task) else call_piece("task", spec, obj) if callable(obj) else obj
    if not isinstance(task, Task):
        raise ValueError(f"task {spec!r} is not a strol_gym Task (got {type(task).__name__})")
    if of is not None and not isinstance(task, of):
        raise ValueError(
            f"task must be a {of.__name__} (or a name / 'module:attr' of one) or None, "
            f"got {type(task).__name__}"
        )
    return task


def task_name(task: Task) -> str:
    """The registry name of ``task``'s class, else its "module:attr" (what a log, a sidecar or
    a suggested command names it by)."""
    from strol_gym.registry import spec_of

    for name in TASKS.names():
        try:
            if TASKS.get(name) is type(task):
                return name
        except ValueError:
            continue
    spec = spec_of(type(task))
    if spec is None:
        raise ValueError(f"task {type(task).__name__} has no registry name or module:attr")
    return spec


__all__ = [
    "TASKS",
    "HighwayTask",
    "RobotTask",
    "Task",
    "make_task",
    "register_task",
    "task_name",
]
