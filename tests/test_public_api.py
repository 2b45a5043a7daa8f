"""Public import paths: the envs' old module paths (before the subpackages by simulator) still
import for one release, each with a DeprecationWarning, and give the new module's objects."""

from __future__ import annotations

import importlib
import sys
import warnings

import numpy as np
import pytest
from gymnasium.envs.registration import load_env_creator

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.envs.moved import MOVED, SPLIT

OLD_ENTRY_POINTS = {
    # what gymnasium registrations and Minari dataset headers written before 0.2 name
    "strol_gym.envs.robot:RobotEnv": "strol_gym.envs.robot.env:RobotEnv",
    "strol_gym.envs.vector_robot:VectorRobotEnv": "strol_gym.envs.robot.vector:VectorRobotEnv",
    "strol_gym.envs.highway:HighwayEnv": "strol_gym.envs.highway.env:HighwayEnv",
    "strol_gym.envs.vector_highway:VectorHighwayEnv": (
        "strol_gym.envs.highway.vector:VectorHighwayEnv"
    ),
    "strol_gym.envs.study:StudyEnv": "strol_gym.envs.study.env:StudyEnv",
    "strol_gym.envs.study_v1:StudyEnvV1": "strol_gym.envs.study.env:StudyEnvV1",
}


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_module_path_warns_and_is_the_new_module(old):
    new = importlib.import_module(MOVED[old])
    sys.modules.pop(old, None)  # an earlier import would not warn again
    with pytest.warns(DeprecationWarning, match=MOVED[old].replace(".", r"\.")):
        module = importlib.import_module(old)
    assert module is new


def test_a_split_module_warns_on_import():
    sys.modules.pop("strol_gym.envs.study_v1", None)
    with pytest.warns(DeprecationWarning, match="strol_gym.envs.study_v1 was split"):
        importlib.import_module("strol_gym.envs.study_v1")


@pytest.mark.parametrize("old", sorted(OLD_ENTRY_POINTS))
def test_old_entry_points_resolve_to_the_same_class(old):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        before = load_env_creator(old)
    assert before is load_env_creator(OLD_ENTRY_POINTS[old])


@pytest.mark.parametrize(
    ("package", "name", "home"),
    [
        ("strol_gym.envs.study", "HOLD", "strol_gym.envs.study.controller"),
        ("strol_gym.envs.study", "TORQUE_LEVER", "strol_gym.envs.study.env"),
        *(("strol_gym.envs.study_v1", n, h) for n, h in SPLIT["strol_gym.envs.study_v1"].items()),
    ],
)
def test_names_of_a_module_that_was_split_warn(package, name, home):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the module's own, on import
        module = importlib.import_module(package)
    with pytest.warns(DeprecationWarning, match=f"{home}.{name}"):
        value = getattr(module, name)
    assert value is getattr(importlib.import_module(home), name)


def test_env_classes_import_from_their_package_without_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        from strol_gym.envs.highway import HighwayEnv, VectorHighwayEnv  # noqa: F401
        from strol_gym.envs.panda import Q_HOME, PandaIK  # noqa: F401
        from strol_gym.envs.robot import RobotEnv, VectorRobotEnv  # noqa: F401
        from strol_gym.envs.study import StudyEnv, StudyEnvV1  # noqa: F401


def test_unknown_name_of_an_env_package_is_an_attribute_error():
    import strol_gym.envs.robot as robot

    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        robot.nope  # noqa: B018


def test_an_env_with_the_old_one_start_hook_still_draws_its_starts():
    from strol_gym.envs.robot import RobotEnv

    with pytest.warns(DeprecationWarning, match="draw_starts"):

        class OldHookEnv(RobotEnv):
            def _draw_start(self, rng):
                return np.array([0.4, 0.0, 0.3]) + 0.0 * rng.random(), rng

    env = OldHookEnv(human=None)
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs["state"], [0.4, 0.0, 0.3], atol=2e-3)
    env.close()
