"""One ``person=`` argument on every env: each form, the person as used, and what a person does
not use refused by name (``strol_gym.humans.spec``, ``strol_gym.envs.study.persons``)."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.humans import HumanSpec

STUDY = ("StROL-Study-v0", "StROL-Study-v1", "StROL-Study-v2")
ALL = ("StROL-Robot-v0", "StROL-Highway-v0", *STUDY)
DEFAULT = {
    "StROL-Robot-v0": HumanSpec("nominal", sigma=0.0, bias=0.0),
    "StROL-Highway-v0": HumanSpec("nominal", sigma=0.0, bias=0.0),
    "StROL-Study-v0": HumanSpec("oracle", sigma=0.0, bias=0.0),
    "StROL-Study-v1": HumanSpec("observer", sigma=0.0, bias=0.0),
    "StROL-Study-v2": HumanSpec("fitted"),
}
REMOVED = ("human", "sigma", "bias", "beta", "human_kwargs", "participant", "user_kwargs")


def make(env_id, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # v0 and v1 of the study
        return gym.make(env_id, **kwargs)


@pytest.mark.parametrize("env_id", ALL)
def test_omitted_is_the_env_s_default_person_as_used(env_id):
    env = make(env_id)
    assert env.unwrapped.person_spec == DEFAULT[env_id]
    env.close()


@pytest.mark.parametrize("env_id", ALL)
@pytest.mark.parametrize("name", REMOVED)
def test_the_old_arguments_are_gone_and_named(env_id, name):
    value = {"human": "nominal", "human_kwargs": {}, "user_kwargs": {}}.get(name, 0.5)
    if name == "participant":
        value = "observer"
    with pytest.raises(ValueError, match=rf"unknown argument\(s\) \['{name}'\].*person="):
        make(env_id, **{name: value})


def test_v2_refuses_sigma_and_the_fitted_person_refuses_what_it_does_not_use():
    with pytest.raises(ValueError, match="sigma"):
        make("StROL-Study-v2", sigma=0.5)
    for field in ("sigma", "bias", "beta"):
        with pytest.raises(ValueError, match=rf"^{field} is not a parameter of person 'fitted'"):
            make("StROL-Study-v2", person=HumanSpec("fitted", **{field: 0.5}))
    with pytest.raises(ValueError, match=r"person kwargs \['mood'\]"):
        make("StROL-Study-v2", person={"kwargs": {"mood": 1}})


@pytest.mark.parametrize(
    ("env_id", "person", "named"),
    [
        ("StROL-Robot-v0", HumanSpec("nominal", beta=5.0), "beta"),
        ("StROL-Highway-v0", {"name": "driver", "beta": 5.0}, "beta"),
        ("StROL-Study-v1", {"beta": 5.0}, "beta"),  # the observer takes σ, ε, no β
        ("StROL-Study-v1", {"kwargs": {"satisfied_regret": 1.0}}, "satisfied_regret"),
        ("StROL-Study-v1", "fitted", "'fitted' is not one of this version's people"),
        ("StROL-Study-v0", {"kwargs": {"threshold": 0.3}}, "threshold"),
    ],
)
def test_a_value_the_person_does_not_use_is_refused_by_name(env_id, person, named):
    with pytest.raises(ValueError, match=named):
        make(env_id, person=person)


def test_every_form_builds_the_same_person():
    spec = HumanSpec("boltzmann", sigma=0.35, bias=0.0)
    forms = [spec, {"name": "boltzmann", "sigma": 0.35, "bias": 0.0}]
    rollouts = []
    for person in forms:
        env = make("StROL-Robot-v0", person=person)
        assert env.unwrapped.person_spec == spec.replace(beta=50.0)  # as used: β filled in
        env.reset(seed=4)
        rollouts.append(np.concatenate([env.step(np.zeros(3))[4]["correction"] for _ in "abc"]))
        env.close()
    np.testing.assert_array_equal(rollouts[0], rollouts[1])
    assert make("StROL-Robot-v0", person="driver").unwrapped.person_spec.name == "driver"


@pytest.mark.parametrize("env_id", ALL)
def test_none_is_no_simulated_person(env_id):
    env = make(env_id, person=None, max_episode_steps=3)
    assert env.unwrapped.person_spec is None
    env.reset(seed=0)
    infos = [env.step(np.zeros(env.action_space.shape, dtype=np.float32))[4] for _ in range(3)]
    assert not any(i["is_correction"] for i in infos)
    if env_id in STUDY:
        assert env.unwrapped.person is None and not any(i["wrench"].any() for i in infos)
    env.close()


def test_the_vector_envs_take_the_person():
    vec = gym.make_vec(
        "StROL-Highway-v0", 2, vectorization_mode="vector_entry_point", person={"sigma": 0.2}
    )
    assert vec.unwrapped.template.person_spec == HumanSpec("nominal", sigma=0.2, bias=0.0)
    vec.close()
    with pytest.raises(ValueError, match="beta"):
        gym.make_vec(
            "StROL-Robot-v0", 2, vectorization_mode="vector_entry_point", person={"beta": 1}
        )


def test_the_study_people_by_name():
    env = make("StROL-Study-v2", person={"name": "observer", "sigma": 0.1}, max_episode_steps=2)
    env.reset(seed=0)
    assert type(env.unwrapped.person).__name__ == "Participant"
    assert env.unwrapped.person.sigma == 0.1
    oracle = make("StROL-Study-v1", person="oracle").unwrapped.person_spec
    assert oracle == HumanSpec("oracle", sigma=0.0, bias=0.0)
    push = make("StROL-Study-v0", person={"kwargs": {"max_push": 1.0}}).unwrapped.person_spec
    assert push.kwargs == {"max_push": 1.0}


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"sigma": -0.1}, "sigma"),
        ({"bias": float("nan")}, "bias"),
        ({"beta": -1.0}, "beta"),
        ({"name": 3}, "person must be"),
        ({"kwargs": {"sigma": 1}}, "must not hold"),
    ],
)
def test_a_bad_field_is_named(fields, match):
    with pytest.raises(ValueError, match=match):
        HumanSpec(**{"name": "nominal", **fields})
    with pytest.raises(ValueError, match=match):
        make("StROL-Robot-v0", person={"name": "nominal", **fields})


def test_a_dict_with_an_unknown_field_is_refused():
    with pytest.raises(ValueError, match=r"person \['noise'\] are not fields"):
        make("StROL-Robot-v0", person={"noise": 0.1})


def test_the_cli_spellings_build_the_person_and_refuse_what_it_does_not_use(capsys, tmp_path):
    from cli_checks import cli_error

    from strol_gym.benchmarks.engine.conditions import custom_condition
    from strol_gym.benchmarks.engine.config import Experiment

    cond = custom_condition("robot", sigma=0.3, bias=0.1, human="boltzmann", beta=5.0)
    assert cond.env_kwargs()["person"] == {
        "name": "boltzmann",
        "sigma": 0.3,
        "bias": 0.1,
        "beta": 5.0,
    }
    used = Experiment("robot", cond, runs=1).person_as_used()
    assert used == {"name": "boltzmann", "sigma": 0.3, "bias": 0.1, "beta": 5.0}
    argv = ["run", "--env", "study1-v2", "--sigma", "0.3", "--runs", "1", "--out", str(tmp_path)]
    assert "sigma is not a parameter of person 'fitted'" in cli_error(argv, capsys)
    argv = ["run", "--env", "robot", "--beta", "3", "--runs", "1", "--out", str(tmp_path)]
    assert "beta is not a parameter of person 'nominal'" in cli_error(argv, capsys)
    assert not any(tmp_path.iterdir())  # refused before a results folder was begun


def test_the_results_folder_records_the_person_as_used(tmp_path):
    import json

    from strol_gym.benchmarks import cli
    from strol_gym.benchmarks.experiments.study import study_config

    v2 = study_config(tasks=(1,), users=1)
    assert v2.persons() == {"study1-v2/simulated-users": {"name": "fitted"}}  # no σ = 0.25
    assert v2.experiments[0].condition.sigma is None
    v1 = study_config(tasks=(1,), users=1, version="v1")
    assert v1.persons() == {
        "study1-v1/simulated-users": {"name": "observer", "sigma": 0.25, "bias": 0.0}
    }
    oracle = study_config((1,), 1, version="v2", participant="oracle").persons()
    assert oracle == {"study1-v2/simulated-users": {"name": "oracle", "sigma": 0.25, "bias": 0.0}}
    argv = ["run", "--env", "highway", "--human", "driver", "--sigma", "0.2", "--runs", "1"]
    argv += ["--learners", "gradient", "--jobs", "1", "--quiet", "--no-plots"]
    assert cli.main([*argv, "--out", str(tmp_path / "r")]) == 0
    meta = json.loads((tmp_path / "r" / "meta.json").read_text())
    assert meta["persons"] == {"highway/custom": {"name": "driver", "sigma": 0.2, "bias": 0.0}}
