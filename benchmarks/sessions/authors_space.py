"""Learners replayed in the authors' feature space, from an imported log's ``authors_poses``.

``strol-paper`` is the paper's StROL as the study ran it (their φ, their ĝ read from
``--authors-ghat GDIR``, λ = 0.25); ``NAME@authors`` is this suite's learner ``NAME`` on the
same φ (:func:`authors_rules.authors_task`). Both are fed what the authors' learner was fed:
each consecutive pair of a correction's logged poses in their hand frame, (x_k, 3Δx_k)
(Task 1: positions only), from the log's ``authors_poses`` (``strol-bench import-study``
writes them). θ̂ there is a weight vector of their features, scored against the same θ*;
regret needs a planner in their feature space, which this project does not have, so it is
left undefined (NaN) for these learners.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.authors_ghat import FLAG
from strol_gym.benchmarks.sessions.authors_rules import (
    PAPER,
    authors_task,
    sample_updates,
    strol_paper,
)
from strol_gym.learners.registry import display_name, make_learner
from strol_gym.tasks.base import Task
from strol_gym.tasks.study import StudyTask

SUFFIX = "@authors"


def in_authors_space(name: str) -> bool:
    """Whether learner ``name`` runs in the authors' feature space."""
    return name == PAPER or name.endswith(SUFFIX)


def check_names(names: Sequence[str], authors_ghat: str | Path | None) -> list[str]:
    """ValueError for ``strol-paper`` without ``--authors-ghat`` (naming the flag) and for a
    ``NAME@authors`` whose NAME is not registered; returns the names the registry checks."""
    from strol_gym.learners.registry import LEARNERS

    rest = []
    for name in names:
        if name == PAPER and authors_ghat is None:
            raise ValueError(
                f"learner {PAPER!r} needs the authors' ĝ: give {FLAG} GDIR (a local checkout's "
                "user_study/g_data)"
            )
        if name.endswith(SUFFIX):
            LEARNERS.check_name(name.removesuffix(SUFFIX))
        elif name != PAPER:
            rest.append(name)
    return rest


def build(name: str, task: Task, authors_ghat: str | Path | None, kwargs: dict[str, Any]) -> Any:
    """Learner ``name`` (:func:`in_authors_space`) for a Study Task, on the authors' φ."""
    if not isinstance(task, StudyTask):
        raise ValueError(f"learner {name!r} runs on the Study Tasks' logs only, not {task.task_id}")
    if name == PAPER:
        return strol_paper(task, authors_ghat)
    return make_learner(name.removesuffix(SUFFIX), task=authors_task(task.number), **kwargs)


def feed(learner: Any, correction: dict[str, Any], where: str) -> None:
    """One logged correction's per-sample updates, from its ``authors_poses``."""
    poses = correction.get("authors_poses")
    if poses is None:
        raise ValueError(
            f"{where}: no 'authors_poses' (the logged poses in the authors' frame): write the "
            "logs with strol-bench import-study to replay learners in the authors' space"
        )
    x, u = sample_updates(poses, learner.task.number)
    for xk, uk in zip(x, u, strict=True):
        learner.update(xk, uk, np.zeros_like(uk))


def label(name: str) -> str:
    """How tables spell an authors'-space learner (others: their display name)."""
    if name == PAPER:
        return "StROL (paper's ĝ, authors' φ)"
    if name.endswith(SUFFIX):
        return f"{display_name(name.removesuffix(SUFFIX))} (authors' φ)"
    return display_name(name)


__all__ = ["SUFFIX", "build", "check_names", "feed", "in_authors_space", "label"]
