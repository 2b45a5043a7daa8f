"""A researcher's learner, human and Task, each in its own file outside
the package, run by name through gymnasium.make, the wrapper and `strol-bench run --jobs 2`."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

LEARNER = '''
import numpy as np
from strol_gym import register_learner
from strol_gym.learners.protocol import LinearRuleLearner


class HalfStep(LinearRuleLearner):
    """θ̂ ← θ̂ + α g / 2."""

    def direction(self, x, u_h, u_r, theta):
        return 0.5 * self.task.g(x, u_h, u_r)


register_learner("half-step", HalfStep)
'''

HUMAN = """
from strol_gym.humans import NominalHuman, register_human


class ShyHuman:
    def __init__(self, task, theta_star, rng, sigma=0.0, bias=0.0, shyness=0.5):
        self.inner = NominalHuman(task, theta_star, rng, sigma=sigma, bias=bias)
        self.theta_star = self.inner.theta_star
        self.shyness = shyness
        self.sigma = sigma

    def act(self, x, u_r, theta_hat):
        return self.shyness * self.inner.act(x, u_r, theta_hat)


register_human("shy", ShyHuman)
"""

TASK = """
import dataclasses
import numpy as np
from strol_gym.tasks import RobotTask, register_task


@dataclasses.dataclass(frozen=True, eq=False)
class NearCupTask(RobotTask):
    cup: np.ndarray = dataclasses.field(default_factory=lambda: np.array([0.60, -0.30, 0.10]))


register_task("near-cup", NearCupTask)
"""

USE = """
import gymnasium as gym
import numpy as np
import my_human, my_learner, my_task  # noqa: F401  (they register their pieces)
from strol_gym.wrappers import OnlineLearningWrapper

env = gym.make("StROL-Robot-v0", person={"name": "shy", "sigma": 0.2, "kwargs": {"shyness": 0.3}},
               task="near-cup")
assert type(env.unwrapped.task).__name__ == "NearCupTask"
assert env.unwrapped.person_spec.name == "shy"
env = OnlineLearningWrapper(env, "half-step")
obs, info = env.reset(seed=1_391)
assert env.unwrapped.human.shyness == 0.3 and env.unwrapped.human.sigma == 0.2
assert type(env.learner).__name__ == "HalfStep"
done = False
while not done:
    obs, reward, terminated, truncated, info = env.step(np.zeros(3, dtype=np.float32))
    done = terminated or truncated
print("error", info["error"])
"""


def _write(folder: Path) -> None:
    for name, text in (
        ("my_learner", LEARNER),
        ("my_human", HUMAN),
        ("my_task", TASK),
        ("use_by_name", USE),
    ):
        (folder / f"{name}.py").write_text(textwrap.dedent(text))


def _env() -> dict:
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)  # nothing but the plugin files' own folder makes them importable
    return env


def test_own_pieces_by_name_through_make_wrapper_and_the_benchmark(tmp_path):
    work = tmp_path / "research"
    work.mkdir()
    _write(work)
    use = subprocess.run(
        [sys.executable, "use_by_name.py"],
        cwd=work,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert use.returncode == 0, use.stderr
    assert use.stdout.startswith("error ")

    cli = Path(sys.executable).with_name("strol-bench")
    out = work / "results"
    args = [
        "run",
        "--env",
        "robot",
        *("--plugin", "my_learner.py", "--plugin", "my_human.py", "--plugin", "my_task.py"),
        *("--learners", "gradient,half-step", "--human", "shy", "--task", "near-cup"),
        *("--human-kwargs", '{"shyness": 0.3}', "--sigma", "0.2"),
        *("--runs", "4", "--block", "2", "--jobs", "2", "--quiet", "--no-plots", "--out", str(out)),
    ]
    run = subprocess.run(
        [str(cli), *args], cwd=work, env=_env(), capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0, run.stderr
    assert "H1" not in run.stdout and "H2" not in run.stdout  # not the paper's comparison
    with open(out / "runs.csv") as f:
        rows = list(csv.DictReader(f))
    assert sorted({r["learner"] for r in rows}) == ["gradient", "half-step"]
    assert len(rows) == 8 and all(float(r["error"]) >= 0 for r in rows)
    config = json.loads((out / "meta.json").read_text())["config"]
    assert config["plugins"] == {
        "learner": {"half-step": "my_learner:HalfStep"},
        "human": {"shy": "my_human:ShyHuman"},
        "task": {"near-cup": "my_task:NearCupTask"},
    }
    assert config["experiments"][0]["task"] == "near-cup"
