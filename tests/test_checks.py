"""strol_gym.checks: one wording for a bad argument, from Python and from the command line.

The parametrised cases put a str, a dict or an object where a number or an array belongs, in the
keyword arguments of every registered env, in the learners' constructors and in ``update``: each
must raise a ValueError/TypeError that names the argument (not numpy's "could not convert").
"""

from __future__ import annotations

import re
import warnings

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.benchmarks.cli import main as bench_main
from strol_gym.learners.registry import make_learner
from strol_gym.tasks.robot import RobotTask

STR, DICT, OBJ = "abc", {"a": 1}, object()
NOT_NUMBERS = (STR, DICT, OBJ)
NOT_DICTS = (STR, OBJ)

# The numeric (and keyword-dict) arguments of every registered env.
# (The person's σ, ε, β and kwargs: tests/test_person.py.)
SHARED = ["n_corrections", "max_episode_steps", "width", "height"]
ENV_ARGS: dict[str, list[str]] = {
    "StROL-Robot-v0": SHARED,
    "StROL-Highway-v0": SHARED,
    "StROL-Study-v0": ["force_threshold", "duration", "stiffness", "rot_stiffness"],
    "StROL-Study-v1": [
        *("reflex_force", "reflex_torque", "reflex_recover", "force_threshold", "duration"),
    ],
    "StROL-Study-v2": [
        *("reflex_force", "reflex_torque", "reflex_recover", "force_threshold", "duration"),
        "hold_off",
    ],
}
LEARNER_ARGS: dict[str, list[str]] = {
    "mof": ["threshold", "n_candidates", "n_hypotheses", "seed"],
    "strol": ["lam"],
    "strol-unrolled": ["lam"],
    "bayes": [
        *("n_particles", "beta", "broad_weight", "mode_jitter", "n_candidates"),
        *("ess_fraction", "bandwidth", "seed", "candidate_seed"),
    ],
    "strol-adaptive": [
        *("lam", "gain", "lam_max", "prior_count", "reference"),
        *("calibration_runs", "calibration_steps"),
    ],
}
UPDATERS = ["gradient", "one", "mof", "e2e", "strol", "bayes", "strol-adaptive", "strol-unrolled"]


def _bad(name: str) -> tuple:
    return NOT_DICTS if name.endswith("_kwargs") else NOT_NUMBERS


def _names_it(err: BaseException, name: str) -> None:
    """The message says '<name> must be ...' (gymnasium's own check of max_episode_steps
    says 'Expect the `max_episode_steps` to be an integer')."""
    msg = str(err)
    assert re.search(rf"(^|[\s`']){re.escape(name)}[`']?( must| to be| \[| \()", msg), msg
    assert "could not convert" not in msg and "invalid literal" not in msg, msg


ENV_CASES = [(e, n, v) for e, names in ENV_ARGS.items() for n in names for v in _bad(n)]
LEARNER_CASES = [(le, n, v) for le, names in LEARNER_ARGS.items() for n in names for v in _bad(n)]
UPDATE_CASES = [(le, a, v) for le in UPDATERS for a in ("x", "u_h", "u_r") for v in NOT_NUMBERS]


def _id(case: tuple) -> str:
    return f"{case[0]}-{case[1]}-{type(case[2]).__name__}"


def test_the_table_covers_every_registered_env():
    assert sorted(i for i in gym.registry if i.startswith("StROL-")) == sorted(ENV_ARGS)


@pytest.mark.parametrize("case", ENV_CASES, ids=_id)
def test_env_kwargs_name_the_argument(case):
    env_id, name, value = case
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # v0 of the study is deprecated
        with pytest.raises((TypeError, ValueError)) as info:
            gym.make(env_id, **{name: value}).close()
    _names_it(info.value, name)


@pytest.mark.parametrize("case", LEARNER_CASES, ids=_id)
def test_learner_constructors_name_the_argument(case):
    learner, name, value = case
    with pytest.raises((TypeError, ValueError)) as info:
        make_learner(learner, task=RobotTask(), **{name: value})
    _names_it(info.value, name)


@pytest.mark.parametrize("case", UPDATE_CASES, ids=_id)
def test_update_names_the_argument(case):
    learner, name, value = case
    online = make_learner(learner, task=RobotTask())
    before = online.theta.copy()
    args = {"x": np.zeros(3), "u_h": np.full(3, 0.05), "u_r": np.zeros(3), name: value}
    with pytest.raises((TypeError, ValueError)) as info:
        online.update(**args)
    _names_it(info.value, name)
    assert np.array_equal(online.theta, before)  # a refused update changes nothing


def test_the_cases_are_about_fifty_arguments():
    args = {(e, n) for e, n, _ in ENV_CASES} | {(le, n) for le, n, _ in LEARNER_CASES}
    args |= {(le, a) for le, a, _ in UPDATE_CASES}
    assert len(args) >= 50


def test_the_command_line_says_what_python_says(capsys):
    with pytest.raises(ValueError) as py:
        gym.make("StROL-Robot-v0", person={"sigma": "abc"})
    with pytest.raises(SystemExit) as cli:
        bench_main(["run", "--env", "robot", "--sigma", "abc"])
    assert cli.value.code == 2
    said = capsys.readouterr().err.strip().splitlines()[-1]
    tail = "sigma must be a number in [0, 100] (a fraction of the action bound), got 'abc'"
    assert said.endswith("--" + tail), said
    assert str(py.value).startswith(tail)


# ------------------------------------------------------------------------- the checks
def test_number_says_the_range_and_keeps_the_value():
    assert checks.number("alpha", 2, low=0, low_open=True) == 2
    assert isinstance(checks.number("n", 3, low=1, integer=True), int)
    assert checks.number("lam", "0.5", low=0, high=10, text=True) == 0.5
    cases = [
        (dict(low=0, low_open=True), -1, "alpha must be a finite number > 0, got -1"),
        (dict(low=1, integer=True), 1.5, "alpha must be an integer >= 1, got 1.5"),
        (dict(low=0, high=1), 2, "alpha must be a number in [0, 1], got 2"),
        (dict(high=1, high_open=True), float("nan"), "alpha must be a finite number < 1, got nan"),
        (dict(), True, "alpha must be a finite number, got True"),
    ]
    for kwargs, value, message in cases:
        with pytest.raises(ValueError, match=re.escape(message)):
            checks.number("alpha", value, **kwargs)


def test_a_value_of_the_wrong_kind_is_a_type_error_and_a_value_error():
    with pytest.raises(checks.ArgumentTypeError) as info:
        checks.number("sigma", "abc")
    assert isinstance(info.value, TypeError) and isinstance(info.value, ValueError)
    with pytest.raises(ValueError, match=re.escape("sigma must be a finite number, got '1'")):
        checks.number("sigma", "1")  # text only where asked for


def test_vector_and_array_check_shape_and_finiteness():
    v = checks.vector("start", [1, 2, 3], 3)
    assert v.dtype == np.float64 and v.tolist() == [1.0, 2.0, 3.0]
    for bad in ([1, 2], "abc", {"a": 1}, [1, np.nan, 3]):
        with pytest.raises(ValueError, match=r"^start must be 3 finite numbers"):
            checks.vector("start", bad, 3)
    assert checks.array("x", [[1, 2]], (None, 2)).shape == (1, 2)
    with pytest.raises(
        ValueError,
        match=re.escape("x must be an array of finite numbers of shape (n, 3), got shape (2,)"),
    ):
        checks.array("x", [1, 2], (None, 3))
    with pytest.raises(ValueError, match="x must be an array of finite numbers, got a NaN"):
        checks.array("x", [np.inf])


def test_names_callables_mappings_and_spaces():
    assert checks.name_in("kind", "e2e", ("strol", "e2e")) == "e2e"
    with pytest.raises(ValueError, match=re.escape("kind must be one of strol, e2e, got 'x'")):
        checks.name_in("kind", "x", ("strol", "e2e"))
    checks.callable_arg("policy", len)
    checks.callable_arg("policy", "pkg.mod:fn", spec=True)
    with pytest.raises(TypeError, match=re.escape("policy must be a callable (task) -> policy")):
        checks.callable_arg("policy", 3, "(task) -> policy")
    assert checks.mapping("human_kwargs", None) == {}
    with pytest.raises(TypeError, match="human_kwargs must be a dict of keyword arguments"):
        checks.mapping("human_kwargs", [("a", 1)])
    assert checks.space_shape("action_space", gym.spaces.Box(-1, 1, (3,))) == (3,)
    with pytest.raises(TypeError, match="action_space must be a space with a shape"):
        checks.space_shape("action_space", object())


def test_registries_use_the_same_words():
    from strol_gym.humans import register_human

    with pytest.raises(
        TypeError, match=re.escape("human 'x' must be a callable (task, theta_star")
    ):
        register_human("x", 3)
