"""The v1 study participant: judges the cup's motion it sees, never θ̂ or the planner's regret."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.envs.study.participant import Participant
from strol_gym.envs.study.people import ParticipantParams
from strol_gym.envs.study.user import SimulatedUser
from strol_gym.tasks.study import StudyTask1

SEED = 20001


@dataclasses.dataclass(frozen=True, eq=False)
class SpyTask(StudyTask1):
    """Task 1 whose regret cannot be asked: the planner's outcome metric."""

    task_id: ClassVar[str] = "spy-study-task1"

    def regret(self, *args, **kwargs):
        raise AssertionError("the participant asked for the planner's regret")


def run(env, n: int) -> list[dict]:
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    return [env.step(zero)[4] for _ in range(n)]


def test_participant_sees_no_theta_hat_and_never_asks_the_regret(monkeypatch):
    seen = []
    wrench = Participant.wrench

    def spy(self, t, x, theta_hat=None):
        seen.append(theta_hat)
        return wrench(self, t, x, theta_hat)

    monkeypatch.setattr(Participant, "wrench", spy)
    env = gym.make("StROL-Study-v1", task=SpyTask(), person={"sigma": 0.0}).unwrapped
    env.reset(seed=SEED)
    assert isinstance(env.person, Participant)
    infos = run(env, 300)
    assert infos[-1]["corrections"] >= 1  # it did judge and push
    assert len(seen) == 300 and all(t is None for t in seen)
    with pytest.raises(AttributeError):
        env.person.satisfied(env.theta_hat)


def test_oracle_participant_is_v0s_user_and_reads_theta_hat():
    env = gym.make("StROL-Study-v1", task=1, person="oracle").unwrapped
    env.reset(seed=SEED)
    assert type(env.person) is SimulatedUser


def test_same_seed_same_participant_rollout():
    def rollout():
        env = gym.make("StROL-Study-v1", task=2, person={"sigma": 0.25}).unwrapped
        env.reset(seed=SEED)
        return [(i["corrections"], i["wrench"].tolist()) for i in run(env, 200)]

    assert rollout() == rollout()


def test_reaction_time_delays_the_first_push():
    def first_push(reaction: float) -> float:
        env = gym.make(
            "StROL-Study-v1", task=1, person={"kwargs": {"reaction": reaction}}
        ).unwrapped
        env.reset(seed=SEED)
        return next(i["time"] for i in run(env, 200) if i["correction_active"])

    quick, slow = first_push(0.0), first_push(1.0)
    assert slow - quick == pytest.approx(1.0, abs=0.11)


def test_an_impatient_participant_gives_up_on_a_robot_that_never_learns():
    # No learner, and θ̂ = −θ*: the robot does the opposite of what the participant wants and
    # no push changes θ̂, so no push improves what it sees.
    env = gym.make("StROL-Study-v1", task=1, person={"kwargs": {"patience": 2}}).unwrapped
    env.reset(seed=SEED)
    env.theta_hat = -env.theta_star
    infos = run(env, 1200)
    assert env.person.gave_up
    last = max(k for k, i in enumerate(infos) if i["correction_active"])
    assert infos[-1]["corrections"] == infos[last]["corrections"] + 1  # none after giving up
    assert env.person.rejections >= 1


def test_its_push_is_greedy_under_its_theta_star():
    task = StudyTask1()
    p = Participant(task, task.theta_star, np.random.default_rng(0))
    x = task.start
    u = p.act(x, np.zeros(3))
    best = task.features(x + u) @ task.theta_star
    others = task.features(x + p._candidates) @ task.theta_star
    assert best >= others.max() - 1e-12
    assert np.all(np.abs(u) <= task.action_bound + 1e-12)


@pytest.mark.parametrize("unused", ["model", "beta", "human_kwargs", "typo"])
def test_built_directly_it_refuses_a_keyword_it_does_not_use_by_name(unused):
    task = StudyTask1()
    with pytest.raises(ValueError, match=rf"does not take \['{unused}'\].*patience"):
        Participant(task, task.theta_star, np.random.default_rng(0), **{unused: 1})
    with pytest.raises(ValueError, match="not both"):
        Participant(
            task, task.theta_star, np.random.default_rng(0), params=ParticipantParams(), patience=3
        )


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"patience": 0}, "patience"),
        ({"reaction": -0.1}, "reaction"),
        ({"window": 0.0}, "window"),
        ({"threshold": float("inf")}, "threshold"),
        ({"push_force": -1.0}, "push_force"),
    ],
)
def test_bad_participant_parameters_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        gym.make("StROL-Study-v1", person={"kwargs": kwargs})


def test_every_pusher_has_the_one_interface_and_frozen_checked_parameters():
    from strol_gym.envs.study.people import (
        HeldWrench,
        ParticipantParams,
        Pusher,
        PushParams,
        ScriptedWrench,
    )

    task = StudyTask1()
    rng = np.random.default_rng(0)
    people = [
        SimulatedUser(task, task.theta_star, rng),
        Participant(task, task.theta_star, rng),
        ScriptedWrench(np.arange(6.0), 2),
        HeldWrench(),
    ]
    for person in people:
        assert isinstance(person, Pusher)
        f, tq = person.wrench(
            0.0, task.start, None if not person.needs_theta_hat else np.zeros(task.dim)
        )
        assert np.shape(f) == (3,) and np.shape(tq) == (3,)
    assert isinstance(people[0].params, PushParams)
    assert isinstance(people[1].params, ParticipantParams)
    assert people[1].params.push_force == 60.0 and people[0].params.push_force == 40.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        people[0].params.tol = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError, match=r"person kwargs\['ramp'\] must be a finite number > 0"):
        PushParams(ramp=0.0)
    with pytest.raises(ValueError, match=r"person kwargs\['patience'\] must be an integer >= 1"):
        ParticipantParams(patience=0)
