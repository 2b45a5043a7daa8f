"""docs/extending.md: its Python blocks run, top to bottom, as one session."""

from __future__ import annotations

import re
import sys
import types
from pathlib import Path

import gymnasium as gym
import pytest

from strol_gym.benchmarks.experiments import EXPERIMENTS
from strol_gym.humans import HUMANS
from strol_gym.tasks import TASKS

PAGE = Path(__file__).resolve().parents[1] / "docs" / "extending.md"


@pytest.mark.filterwarnings("ignore:.*Box observation space m:UserWarning")  # φ's unbounded side
def test_extending_examples_run(capsys):
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)
    assert len(blocks) >= 4, "docs/extending.md lost its examples"
    # A real module, as a user's file would be (dataclasses and pickle look classes up there).
    module = types.ModuleType("extending_example")
    sys.modules[module.__name__] = module
    namespace = module.__dict__
    try:
        for i, block in enumerate(blocks):
            exec(compile(block, f"{PAGE}:block{i}", "exec"), namespace)
        out = capsys.readouterr().out.split("\n")
    finally:
        pieces = ((TASKS, "point"), (TASKS, "near-cup"), (HUMANS, "shy"))
        for reg, name in (*pieces, (EXPERIMENTS, "noise-sweep")):
            if name in reg:
                reg.unregister(name)
        gym.registry.pop("Point-v0", None)
        del sys.modules[module.__name__]
    assert out[0] == "NearCupTask"
    assert out[1].startswith("True [")  # the shy human corrected on the first step
    error = float(out[2].split()[1])
    assert 0.0 <= error < 5.0
    # the experiment of one's own ran through the CLI: its table, printed and written
    assert "| σ | learner | final error |" in out
    rows = [line for line in out if line.startswith("| 0")]
    assert len(rows) == 4  # 2 noise levels x Gradient, StROL
    assert any(line.startswith("wrote ") and line.endswith("noise-sweep.csv") for line in out)
