"""One open registry: names or module:attr for learners, humans, Tasks and conditions."""

from __future__ import annotations

import dataclasses
import re

import gymnasium as gym
import numpy as np
import pytest
import registry_pieces
from registry_pieces import HalfGradient, NearCupTask, shy_human

import strol_gym
from strol_gym.benchmarks.cli import main
from strol_gym.benchmarks.engine.conditions import (
    CONDITIONS,
    ENVS,
    Condition,
    EnvPreset,
    custom_condition,
    make_condition,
    register_condition,
    register_env_preset,
)
from strol_gym.benchmarks.engine.config import BenchConfig, Experiment
from strol_gym.benchmarks.engine.runner import run_benchmark
from strol_gym.benchmarks.engine.worker import Worker as _Worker
from strol_gym.humans import HUMANS, register_human
from strol_gym.learners.registry import LEARNERS, register_learner
from strol_gym.learners.training import TrainConfig, sample_batch
from strol_gym.registry import registries, spec_of, user_specs
from strol_gym.tasks import TASKS, make_task, register_task
from strol_gym.wrappers import OnlineLearningWrapper

PIECES = "registry_pieces"


@pytest.fixture
def registered():
    """Register one piece of each kind by name; remove them afterwards."""
    register_learner("half", HalfGradient, display="Half")
    register_human("shy", shy_human)
    register_task("near-cup", NearCupTask)
    register_condition("shy-clean", Condition("shy-clean", sigma=0.0, human="shy"))
    register_env_preset(EnvPreset("robot-3", "StROL-Robot-v0", 20, 3, 0.1, "error"))
    yield
    for reg, name in ((LEARNERS, "half"), (HUMANS, "shy"), (TASKS, "near-cup"), (ENVS, "robot-3")):
        if name in reg:
            reg.unregister(name)
    CONDITIONS.unregister("shy-clean")


def test_every_registry_lists_its_built_ins_and_rejects_unknown_names():
    regs = registries()
    assert set(regs) == {"env", "learner", "human", "task", "condition", "prior", "robot"}
    assert regs["learner"].names()[:5] == ["gradient", "one", "mof", "e2e", "strol"]
    assert "nominal" in regs["human"] and "robot" in regs["task"]
    assert regs["prior"].names()[:2] == ["bimodal", "uniform"]
    assert regs["robot"].names()[:2] == ["task", "zeros"]
    for kind, reg in regs.items():
        if kind == "env":
            continue  # presets are data, looked up by key (env_preset)
        with pytest.raises(ValueError, match=f"unknown {kind} 'nope'; known {kind}s: "):
            reg.get("nope")
        with pytest.raises(ValueError, match="already registered"):
            reg.register(reg.names()[0], "a.b:c")
        with pytest.raises(ValueError, match="cannot be removed"):
            reg.unregister(reg.names()[0])
    with pytest.raises(ValueError, match="cannot import"):
        LEARNERS.get("no_such_module_xyz:Thing")


def test_names_and_module_attr_work_everywhere(registered):
    # gymnasium.make: human and task by name and by module:attr
    for human, task in (("shy", "near-cup"), (f"{PIECES}:shy_human", f"{PIECES}:NearCupTask")):
        registry_pieces.SEEN.clear()
        env = gym.make(
            "StROL-Robot-v0",
            person={"name": human, "sigma": 0.1, "kwargs": {"shyness": 0.25}},
            task=task,
        )
        assert isinstance(env.unwrapped.task, NearCupTask)
        # the wrapper and make_learner: a name and a module:attr
        for learner in ("half", f"{PIECES}:HalfGradient"):
            wrapped = OnlineLearningWrapper(env, learner)
            assert isinstance(wrapped.learner, HalfGradient)
            wrapped.reset(seed=0)
            _, _, _, _, info = wrapped.step(np.zeros(3, np.float32))
            assert info["is_correction"]
        want = {"sigma": 0.1, "bias": 0.0, "beta": 50.0, "shyness": 0.25}
        assert registry_pieces.SEEN[-1] == want
        env.close()
    assert isinstance(strol_gym.make_learner("half", task=make_task("robot")), HalfGradient)
    assert isinstance(make_task("StROL-Highway-v0"), strol_gym.HighwayTask)  # an env id
    cond = make_condition("robot", "shy-clean")
    assert cond.env_kwargs()["person"]["name"] == "shy"


def test_a_custom_human_trains_by_name(registered):
    registry_pieces.SEEN.clear()
    cfg = TrainConfig(human="shy", sigma=0.2, beta=3.0, human_kwargs={"shyness": 0.5})
    task = make_task("robot")
    batch = sample_batch(task, np.random.default_rng(0), 4, cfg)
    assert batch["u_h"].shape == (4, 3) and np.isfinite(batch["u_h"]).all()
    assert registry_pieces.SEEN == [{"sigma": 0.2, "bias": 0.0, "beta": 3.0, "shyness": 0.5}] * 4
    again = sample_batch(task, np.random.default_rng(0), 4, cfg)
    np.testing.assert_array_equal(batch["u_h"], again["u_h"])
    with pytest.raises(ValueError, match="unknown human"):
        TrainConfig(human="nobody")


def test_user_entries_travel_to_a_fresh_worker_as_specs(registered):
    exp = Experiment("robot-3", custom_condition("robot-3", human="shy"), runs=1, task="near-cup")
    config, stuck = BenchConfig((exp,), ("gradient", "half"), "gradient").with_user_specs()
    assert stuck == []
    assert config.plugins == {
        "env": {"robot-3": dataclasses.asdict(ENVS.table["robot-3"])},
        "learner": {"half": f"{PIECES}:HalfGradient"},
        "human": {"shy": f"{PIECES}:shy_human"},
        "task": {"near-cup": f"{PIECES}:NearCupTask"},
    }
    shipped = config.to_dict()
    # A fresh process knows none of the user's names: simulate it by removing them.
    for reg, name in ((LEARNERS, "half"), (HUMANS, "shy"), (TASKS, "near-cup"), (ENVS, "robot-3")):
        reg.unregister(name)
    worker = _Worker(BenchConfig.from_dict(shipped))
    records = worker.run_unit(worker.config.units()[0])
    worker.close()
    assert {r["learner"] for r in records} == {"gradient", "half"}
    assert {r["steps"] for r in records} == {3}  # the preset's correction count
    assert "half" in LEARNERS and "shy" in HUMANS and "near-cup" in TASKS and "robot-3" in ENVS


def test_a_lambda_cannot_reach_workers_and_the_error_says_so(tmp_path):
    assert spec_of(lambda task: None) is None
    assert spec_of(HalfGradient) == f"{PIECES}:HalfGradient"
    register_learner("lam", lambda task, **kw: HalfGradient(task))
    try:
        assert user_specs({"learner": ["lam"]}) == ({}, ["learner 'lam'"])
        exp = Experiment("robot", custom_condition("robot"), runs=2)
        config = BenchConfig((exp,), ("gradient", "lam"), "gradient", block=1)
        with pytest.raises(ValueError, match="learner 'lam' cannot reach the worker processes"):
            run_benchmark(config, tmp_path / "r", jobs=2, quiet=True)
    finally:
        LEARNERS.unregister("lam")


def test_cli_list_shows_plugins_and_run_takes_user_names(tmp_path, capsys):
    plugin = tmp_path / "my_plugin_mod.py"
    plugin.write_text(
        "from strol_gym.learners.registry import register_learner\n"
        "register_learner('plugged', 'strol_gym.learners.rules:OneLearner')\n"
    )
    try:
        assert main(["list", "--plugin", str(plugin)]) == 0
        out = capsys.readouterr().out
        assert "plugged (yours)" in out and "humans: nominal" in out and "tasks: robot" in out
        shipped = [f"{n} (yours)" for reg in registries().values() for n in reg.builtin]
        assert not [s for s in shipped if s in out], "only what a user registered is marked"
    finally:
        LEARNERS.unregister("plugged")
    with pytest.raises(SystemExit) as e:
        main(["run", "--env", "robot", "--condition", "windy", "--runs", "1"])
    assert e.value.code == 2
    assert "unknown condition 'windy'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("source", "message"),
    [
        ("raise RuntimeError('boom')", "failed to import: RuntimeError: boom"),
        ("def broken(:\n", "failed to import: SyntaxError"),
        ("import sys\nsys.exit(3)", r"called sys.exit\(3\) on import"),
    ],
)
def test_a_bad_plugin_exits_2_with_a_message(tmp_path, capsys, source, message):
    plugin = tmp_path / f"bad_plugin_{len(source)}.py"
    plugin.write_text(source)
    with pytest.raises(SystemExit) as e:
        main(["list", "--plugin", str(plugin)])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and re.search(message, err)
    with pytest.raises(SystemExit):
        main(["list", "--plugin", str(tmp_path / "missing.py")])
    assert "no such file" in capsys.readouterr().err
