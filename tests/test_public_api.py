"""Every import path and name the README and docs/ show imports; the names removed before the
first release (CHANGELOG.md, "Removed") are gone, not aliased.

``SHOWN`` pins the names the pages show (``grep -ohE`` of ``from strol_gym... import ...`` lines
and of dotted ``strol_gym.x.y`` names in README.md and docs/*.md);
``test_what_the_docs_show_today_imports`` reads today's pages.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

import strol_gym  # noqa: F401  (registers the envs)

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
    "strol_gym.humans.spec:person_spec",
    "strol_gym.humans.spec:DEFAULT_PERSON",
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
    "strol_gym.envs.contract:CorrectionEnv",
    "strol_gym.envs.robot.vector:VectorRobotEnv",
    "strol_gym.envs.highway.vector:VectorHighwayEnv",
    "strol_gym.envs.study.user:SimulatedUser",
    "strol_gym.envs.study.persons:StudyPerson",
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
]

REMOVED_MODULES = [
    # old module paths, each removed in favour of the module CHANGELOG.md names
    "strol_gym.sb3",
    "strol_gym.deprecation",
    "strol_gym.humans.model",
    "strol_gym.humans.models",
    "strol_gym.humans.fitting",
    "strol_gym.envs.moved",
    "strol_gym.envs.base",
    "strol_gym.envs.vector_base",
    "strol_gym.envs.panda_ik",
    "strol_gym.envs.panda_ik_batched",
    "strol_gym.envs.robot_scene",
    "strol_gym.envs.robot_seeds",
    "strol_gym.envs.vector_robot",
    "strol_gym.envs.vector_highway",
    "strol_gym.envs.study_participant",
    "strol_gym.envs.study_user",
    "strol_gym.envs.study_scene",
    "strol_gym.envs.study_v1",
    "strol_gym.benchmarks.engine.study_authors",
]

REMOVED_NAMES = [
    "strol_gym.humans:ModelHuman",
    "strol_gym.humans:TeacherModel",
    "strol_gym.envs.study:HOLD",
    "strol_gym.envs.study:Velocity",
    "strol_gym.envs.study:K_NULL",
    "strol_gym.envs.study:D_NULL",
    "strol_gym.envs.study:END_HOLD",
    "strol_gym.envs.study:TORQUE_LEVER",
    "strol_gym.humans.spec:check_shared",
]

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


@pytest.mark.parametrize("spec", SHOWN)
def test_a_name_the_docs_show_imports(spec):
    assert resolve(spec) is not None


@pytest.mark.parametrize("old", REMOVED_MODULES)
def test_a_removed_module_path_is_gone(old):
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module(old)


@pytest.mark.parametrize("spec", REMOVED_NAMES)
def test_a_removed_name_is_an_attribute_error(spec):
    module, _, attr = spec.partition(":")
    with pytest.raises(AttributeError, match=attr):
        getattr(importlib.import_module(module), attr)


def test_the_changelog_lists_every_removal():
    changelog = (ROOT / "CHANGELOG.md").read_text()
    # [Unreleased] and the newest release (0.1.0 holds the removals it shipped)
    sections = changelog.split("\n## [")[1:3]
    removed = "".join(
        s.split("### Removed", 1)[1].split("\n### ", 1)[0] for s in sections if "### Removed" in s
    )
    missing = [
        spec for spec in [*REMOVED_MODULES, *REMOVED_NAMES] if spec.replace(":", ".") not in removed
    ]
    assert not missing, (
        f"CHANGELOG.md's Removed ([Unreleased] or the newest release) lacks {missing}"
    )


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
    """Pages change: every name they show now must import."""
    broken = []
    for spec in sorted(_shown_today()):
        try:
            _resolve_dotted(spec)
        except (ImportError, AttributeError) as e:
            broken.append(f"{spec}: {e}")
    assert not broken, "names the docs show that do not import: " + "; ".join(broken)


def test_env_classes_import_from_their_package():
    from strol_gym.envs.highway import HighwayEnv, VectorHighwayEnv  # noqa: F401
    from strol_gym.envs.panda import Q_HOME, PandaIK  # noqa: F401
    from strol_gym.envs.robot import RobotEnv, VectorRobotEnv  # noqa: F401
    from strol_gym.envs.study import StudyEnv, StudyEnvV1  # noqa: F401


def test_unknown_name_of_an_env_package_is_an_attribute_error():
    import strol_gym.envs.robot as robot

    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        robot.nope  # noqa: B018
