"""Every import path and name the README and docs/ show keeps working; renamed ones for one
release, as aliases that warn (CHANGELOG.md lists them).

``SHOWN`` was built from README.md and docs/*.md at 59bd92e (``grep -ohE`` of ``from strol_gym...
import ...`` lines and of dotted ``strol_gym.x.y`` names), so it holds what users were shown
before this release's moves; ``test_what_the_docs_show_today_imports`` reads today's pages.
"""

from __future__ import annotations

import importlib
import re
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from gymnasium.envs.registration import load_env_creator

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.envs.study_v1 import NAMES as STUDY_V1_NAMES

ROOT = Path(__file__).resolve().parents[1]

SHOWN = [
    # the package's top
    "strol_gym",
    "strol_gym:RobotTask",
    "strol_gym:HighwayTask",
    "strol_gym:NominalHuman",
    "strol_gym:OnlineRewardLearner",
    "strol_gym:make_learner",
    "strol_gym:register_learner",
    "strol_gym:list_learners",
    # Tasks, priors, planning, registries
    "strol_gym.tasks:Task",
    "strol_gym.tasks:RobotTask",
    "strol_gym.tasks:register_task",
    "strol_gym.tasks.study",
    "strol_gym.priors:MixturePrior",
    "strol_gym.priors:Prior",
    "strol_gym.priors:HedgedPrior",
    "strol_gym.planning:plan_linear_reward",
    "strol_gym.registry:Registry",
    "strol_gym.registration",
    # humans
    "strol_gym.humans:HumanModel",
    "strol_gym.humans:HumanSpec",
    "strol_gym.humans:NominalHuman",
    "strol_gym.humans:register_human",
    "strol_gym.humans.zoo",
    "strol_gym.humans.population",
    # learners
    "strol_gym.learners.training:TrainConfig",
    "strol_gym.learners.training:train_correction",
    "strol_gym.learners.training:heldout_lyapunov",
    "strol_gym.learners.protocol:LinearRuleLearner",
    "strol_gym.learners.correction:StROLLearner",
    "strol_gym.learners.correction:UnrolledStROLLearner",
    "strol_gym.learners.checkpoint:save_checkpoint",
    "strol_gym.learners.simulate:simulate_errors",
    "strol_gym.learners.registry:LEARNERS",
    "strol_gym.learners.bayes:BayesLearner",
    "strol_gym.learners.adaptive:AdaptiveStROLLearner",
    "strol_gym.analysis:basin_map",
    "strol_gym.testing:check_learner",
    "strol_gym.testing:check_task",
    "strol_gym.testing:check_human",
    # envs
    # (the envs' old module paths, e.g. strol_gym.envs.base, moved to subpackages by simulator:
    # envs.moved.MOVED, tested below; their new homes here)
    "strol_gym.envs.contract:CorrectionEnv",
    "strol_gym.envs.robot.vector:VectorRobotEnv",
    "strol_gym.envs.highway.vector:VectorHighwayEnv",
    "strol_gym.envs.study.user:SimulatedUser",
    "strol_gym.envs.robot.seeds",
    "strol_gym.envs.panda.ik_batched",
    # wrappers
    "strol_gym.wrappers:OnlineLearningWrapper",
    "strol_gym.wrappers:VectorOnlineLearningWrapper",
    "strol_gym.wrappers.sb3:SB3VecEnv",
    # the benchmark
    "strol_gym.benchmarks.cli:main",
    "strol_gym.benchmarks.args:float_list",
    "strol_gym.benchmarks.args:positive_int",
    "strol_gym.benchmarks.args:run_options",
    "strol_gym.benchmarks.train",
    "strol_gym.benchmarks.engine.config:BenchConfig",
    "strol_gym.benchmarks.engine.config:Experiment",
    "strol_gym.benchmarks.engine.conditions:Condition",
    "strol_gym.benchmarks.engine.conditions:EnvPreset",
    "strol_gym.benchmarks.engine.conditions:register_condition",
    "strol_gym.benchmarks.engine.conditions:register_env_preset",
    "strol_gym.benchmarks.engine.robots:register_robot",
    "strol_gym.envs.study.metrics",
    "strol_gym.benchmarks.experiments:register_experiment",
    "strol_gym.benchmarks.experiments.base:BenchExperiment",
    "strol_gym.benchmarks.experiments.base:Outcome",
    "strol_gym.benchmarks.experiments.study_seed_sets",
    "strol_gym.benchmarks.analysis.compare_learners",
]

MOVED = {
    # old "module:attr" -> new "module:attr"; each warns for one release, then goes
    "strol_gym.sb3:SB3VecEnv": "strol_gym.wrappers.sb3:SB3VecEnv",
    "strol_gym.humans:ModelHuman": "strol_gym.humans:SimulatedHuman",
    "strol_gym.humans:TeacherModel": "strol_gym.humans:NominalModel",
    "strol_gym.humans.model:ModelHuman": "strol_gym.humans.interface:SimulatedHuman",
    "strol_gym.humans.model:HumanModel": "strol_gym.humans.interface:HumanModel",
    "strol_gym.humans.model:Human": "strol_gym.humans.interface:Human",
    "strol_gym.humans.models:TeacherModel": "strol_gym.humans.builtin:NominalModel",
    "strol_gym.humans.models:NominalHuman": "strol_gym.humans.builtin:NominalHuman",
}

# Dotted names in the docs that are not import paths: an entry-point group, a placeholder, the
# ``python -m`` entry (importing it runs the CLI).
NOT_IMPORTS = {
    "strol_gym.plugins",
    "strol_gym.benchmarks.speed.NAME",
    "strol_gym.benchmarks.__main__",
}


def resolve(spec: str) -> object:
    module, _, attr = spec.partition(":")
    obj = importlib.import_module(module)
    return getattr(obj, attr) if attr else obj


def _our_deprecations(caught: list[warnings.WarningMessage]) -> list[str]:
    return [
        str(w.message)
        for w in caught
        if issubclass(w.category, DeprecationWarning) and "old name goes" in str(w.message)
    ]


@pytest.mark.parametrize("spec", SHOWN)
def test_a_name_the_docs_showed_imports_without_warning(spec):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert resolve(spec) is not None
    assert not _our_deprecations(caught), spec


@pytest.mark.parametrize(("old", "new"), sorted(MOVED.items()))
def test_an_old_name_still_works_and_warns(old, new):
    module, _, attr = old.partition(":")
    with pytest.warns(DeprecationWarning, match=r"the old name goes in the next release"):
        obj = getattr(importlib.import_module(module), attr)
    assert obj is resolve(new)


def test_from_import_of_an_old_name_works_and_warns():
    with pytest.warns(DeprecationWarning, match=r"strol_gym\.sb3\.SB3VecEnv is now"):
        from strol_gym.sb3 import SB3VecEnv
    from strol_gym.wrappers.sb3 import SB3VecEnv as new

    assert SB3VecEnv is new


def test_an_unknown_name_is_still_an_attribute_error():
    import strol_gym.humans

    with pytest.raises(AttributeError, match="NoSuchHuman"):
        strol_gym.humans.NoSuchHuman  # noqa: B018


def _shown_today() -> set[str]:
    """``module:attr`` / ``module`` specs of every strol_gym name README.md and docs/ show."""
    text = "\n".join(p.read_text() for p in [ROOT / "README.md", *sorted(ROOT.glob("docs/*.md"))])
    specs: set[str] = set()
    for module, names in re.findall(r"from (strol_gym[\w.]*) import ([\w, ]+)", text):
        specs.update(f"{module}:{n.strip()}" for n in names.split(",") if n.strip())
    for dotted in re.findall(r"\bstrol_gym(?:\.\w+)+", text):
        if dotted not in NOT_IMPORTS:
            specs.add(dotted)
    return specs


def _resolve_dotted(spec: str) -> object:
    """``a.b.C`` -> the longest importable module prefix, then attributes."""
    if ":" in spec:
        return resolve(spec)
    parts = spec.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return obj
    raise ModuleNotFoundError(spec)


def test_what_the_docs_show_today_imports():
    """Pages change: every name they show now must import (a new name, or an alias)."""
    broken = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for spec in sorted(_shown_today()):
            try:
                _resolve_dotted(spec)
            except (ImportError, AttributeError) as e:
                broken.append(f"{spec}: {e}")
    assert not broken, "names the docs show that do not import: " + "; ".join(broken)


# ---------------------------------------------------------------- the envs' old module paths
MOVED_MODULES = {
    # old module -> new module (the old one warns and is the new one)
    "strol_gym.envs.base": "strol_gym.envs.contract",
    "strol_gym.envs.vector_base": "strol_gym.envs.vector",
    "strol_gym.envs.panda_ik": "strol_gym.envs.panda.ik",
    "strol_gym.envs.panda_ik_batched": "strol_gym.envs.panda.ik_batched",
    "strol_gym.envs.robot_scene": "strol_gym.envs.robot.scene",
    "strol_gym.envs.robot_seeds": "strol_gym.envs.robot.seeds",
    "strol_gym.envs.vector_robot": "strol_gym.envs.robot.vector",
    "strol_gym.envs.vector_highway": "strol_gym.envs.highway.vector",
    "strol_gym.envs.study_participant": "strol_gym.envs.study.participant",
    "strol_gym.envs.study_user": "strol_gym.envs.study.user",
    "strol_gym.envs.study_scene": "strol_gym.envs.study.scene",
    "strol_gym.benchmarks.engine.study_authors": "strol_gym.envs.study.metrics",
}

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


@pytest.mark.parametrize("old", sorted(MOVED_MODULES))
def test_old_module_path_warns_and_is_the_new_module(old):
    new = importlib.import_module(MOVED_MODULES[old])
    sys.modules.pop(old, None)  # an earlier import would not warn again
    with pytest.warns(DeprecationWarning, match=r"the old name goes in the next release"):
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
        *(("strol_gym.envs.study_v1", n, h) for n, h in STUDY_V1_NAMES.items()),
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
