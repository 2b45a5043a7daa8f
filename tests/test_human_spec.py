"""One value for the human's arguments: the envs build it from their flat keyword arguments,
accept it whole, and the study envs read it too."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.humans.spec import HumanSpec


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"sigma": -0.1}, "sigma"),
        ({"bias": float("nan")}, "bias"),
        ({"beta": -1.0}, "beta"),
        ({"name": 3}, "human must be"),
        ({"name": "no-such-human"}, "unknown human 'no-such-human'"),
        ({"kwargs": {"mood": 1}}, r"human_kwargs \['mood'\] are not parameters"),
        ({"name": None, "kwargs": {"switch_after": 2}}, "without a human model"),
    ],
)
def test_a_bad_field_is_named(fields, match):
    with pytest.raises(ValueError, match=match):
        HumanSpec(**fields)


def test_the_spec_and_the_flat_arguments_build_the_same_episode():
    spec = HumanSpec("changing", sigma=0.2, bias=0.1, kwargs={"switch_after": 2})
    flat = {"human": "changing", "sigma": 0.2, "bias": 0.1, "human_kwargs": {"switch_after": 2}}
    rollouts = []
    for kwargs in ({"human": spec}, flat):
        env = gym.make("StROL-Robot-v0", **kwargs)
        assert env.unwrapped.human_spec == spec
        env.reset(seed=4)
        corrections = [env.step(np.zeros(3))[4]["correction"] for _ in range(4)]
        rollouts.append(np.concatenate(corrections))
        env.close()
    np.testing.assert_array_equal(rollouts[0], rollouts[1])


def test_arguments_beside_a_spec_are_refused():
    with pytest.raises(ValueError, match=r"\['sigma'\] given beside human=HumanSpec"):
        gym.make("StROL-Robot-v0", human=HumanSpec(), sigma=0.3)


def test_no_human_means_no_corrections_in_any_env():
    env = gym.make("StROL-Robot-v0", human=None)
    env.reset(seed=0)
    infos = [env.step(np.zeros(3))[4] for _ in range(3)]
    assert not any(i["is_correction"] for i in infos)
    assert all(not i["correction"].any() for i in infos)
    env.close()


def test_the_study_env_takes_the_spec():
    env = gym.make("StROL-Study-v1", human=HumanSpec(sigma=0.1), max_episode_steps=3)
    assert env.unwrapped.sigma == 0.1 and env.unwrapped.user_enabled
    env.close()
    with pytest.raises(RuntimeError, match="call reset"):
        gym.make("StROL-Study-v1", human=None).unwrapped.step(np.zeros(3))


def test_a_condition_builds_the_env_s_spec():
    from strol_gym.benchmarks.engine.conditions import Condition
    from strol_gym.benchmarks.engine.config import Experiment

    cond = Condition("c", sigma=0.1, human="changing", human_kwargs={"switch_after": 3})
    exp = Experiment("robot", cond, runs=1)
    env = gym.make(exp.env_id, **exp.env_kwargs())
    assert env.unwrapped.human_spec == exp.condition.human_spec()
    env.close()
