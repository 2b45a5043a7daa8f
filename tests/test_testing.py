"""strol_gym.testing: every registered piece passes the checks, and broken pieces fail them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_learners import LinearTask

from strol_gym.humans import HUMANS, NominalHuman
from strol_gym.learners.registry import list_learners
from strol_gym.learners.rules import GradientLearner
from strol_gym.tasks import TASKS, make_task
from strol_gym.testing import check_human, check_learner, check_task

V1_TASKS = [name for name in TASKS.names() if name.startswith("study-") and name.endswith("-v1")]
"""StROL-Study-v1's Tasks: v0's Tasks under their own task_id (so learners find v1's ĝ), so
v0's checks of φ, g, planner and humans are theirs; checked once below for what differs."""
V2_TASKS = [name for name in TASKS.names() if name.startswith("study-") and name.endswith("-v2")]
"""StROL-Study-v2's Tasks: v0's features and g with v2's planner (tests/test_study_v2.py) and
v2's own StROL and e2e ĝ (no strol-unrolled or e2e-scratch ĝ: those learners are not the
study's); checked once below for what differs."""
TASKS_CHECKED = [name for name in TASKS.names() if name not in V1_TASKS + V2_TASKS]


@pytest.mark.parametrize("task", TASKS_CHECKED)
def test_every_registered_task_passes(task):
    check_task(make_task(task))


@pytest.mark.parametrize("task", TASKS_CHECKED)
@pytest.mark.parametrize("learner", list_learners())
def test_every_registered_learner_passes(learner, task):
    check_learner(learner, make_task(task))


def test_study_v1_tasks_are_v0s_with_their_own_id():
    """Each v1 Task is its v0 Task (same fields, a subclass) with its own task_id, and StROL
    finds the ĝ shipped for it."""
    assert V1_TASKS == ["study-task1-v1", "study-task2-v1", "study-task3-v1"]
    for k, name in enumerate(V1_TASKS, start=1):
        v1, v0 = make_task(name), make_task(f"study-task{k}")
        assert isinstance(v1, type(v0)) and v1.task_id == f"StROL-Study-v1-task{k}"
        assert dataclasses.asdict(v1).keys() == dataclasses.asdict(v0).keys()
        assert v1.describe()["feature_names"] == v0.describe()["feature_names"]
    check_learner("strol", make_task(V1_TASKS[0]))


def test_study_v2_tasks_have_their_own_id_and_ghat():
    assert V2_TASKS == ["study-task1-v2", "study-task2-v2", "study-task3-v2"]
    for k, name in enumerate(V2_TASKS, start=1):
        v2, v0 = make_task(name), make_task(f"study-task{k}")
        assert isinstance(v2, type(v0)) and v2.task_id == f"StROL-Study-v2-task{k}"
        assert v2.describe()["feature_names"] == v0.describe()["feature_names"]
    check_learner("strol", make_task(V2_TASKS[0]))


@pytest.mark.parametrize("task", TASKS_CHECKED)
@pytest.mark.parametrize("human", HUMANS.names())
def test_every_registered_human_passes(human, task):
    check_human(human, make_task(task))


@dataclasses.dataclass(frozen=True, eq=False)
class BatchMixingTask(LinearTask):
    """φ centred on the batch mean: right for one state, wrong for a batch."""

    def features(self, x):
        x = np.asarray(x, dtype=np.float64)
        phi = super().features(x)
        return phi - phi.mean(axis=0) if phi.ndim == 2 else phi


@dataclasses.dataclass(frozen=True, eq=False)
class DriftingGTask(LinearTask):
    """A g that moves θ̂ even without a correction."""

    def g(self, x, u_h, u_r):
        return super().g(x, u_h, u_r) + 0.1


@dataclasses.dataclass(frozen=True, eq=False)
class SwappedPlanesTask(LinearTask):
    """A g_planes (what eq. M6's search reads) whose features come in the wrong order."""

    def g_planes(self, x, u_h, u_r):
        return super().g_planes(x, u_h, u_r)[::-1]


@pytest.mark.parametrize(
    ("task", "match"),
    [
        (BatchMixingTask(), "features: batched row 0 vs a single state"),
        (DriftingGTask(), r"g\(x, 0, u_R\) \(no correction, nothing to learn\) must be 0"),
        (SwappedPlanesTask(), "g_planes vs g"),
    ],
)
def test_a_broken_task_fails_with_a_message(task, match):
    with pytest.raises(AssertionError, match=match):
        check_task(task)


class Forgetful(GradientLearner):
    """Its state_dict does not restore θ̂."""

    def load_state_dict(self, state):
        pass


class Jittery(GradientLearner):
    """Adds unseeded noise to every update."""

    def update(self, x, u_h, u_r=None):
        super().update(x, u_h, u_r)
        self.theta = self.theta + 1e-3 * np.random.default_rng().standard_normal(self.theta.shape)
        return self.theta.copy()


@pytest.mark.parametrize(
    ("learner", "match"),
    [(Forgetful, r"load_state_dict\(state_dict\(\)\)"), (Jittery, "determinism")],
)
def test_a_broken_learner_fails_with_a_message(learner, match):
    with pytest.raises(AssertionError, match=match):
        check_learner(learner, LinearTask())


def test_a_human_that_ignores_its_generator_fails():
    def careless(task, theta_star, rng, sigma=0.0):
        return NominalHuman(task, theta_star, np.random.default_rng(), sigma=sigma)

    with pytest.raises(AssertionError, match="same generator seed"):
        check_human(careless, LinearTask())
    check_human(NominalHuman, LinearTask(), sigma=0.2)
