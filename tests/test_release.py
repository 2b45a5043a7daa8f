"""The release and the lean core: setup.cfg, CITATION.cff and CHANGELOG.md name one version and
one day; the core runs without any extra (training the same ĝ); strol-bench without its
``[bench]`` extra exits 2 naming it."""

from __future__ import annotations

import configparser
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

from strol_gym.benchmarks import cli

ROOT = Path(__file__).resolve().parents[1]
# what the core must run without: every extra's packages but highway-env's own (matplotlib)
EXTRAS_ONLY = ("tqdm", "stable_baselines3", "imageio", "minari", "ray", "submitit", "numba")


def _cfg() -> configparser.ConfigParser:
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    return cfg


def test_setup_citation_and_changelog_name_one_release():
    version = _cfg()["metadata"]["version"]
    assert re.fullmatch(r"\d+\.\d+\.\d+", version), version
    citation = (ROOT / "CITATION.cff").read_text()
    assert re.search(rf"^version: {re.escape(version)}$", citation, re.M)
    released = re.search(r"^date-released: (\d{4}-\d{2}-\d{2})$", citation, re.M)
    assert released, "CITATION.cff has no date-released"
    headings = re.findall(r"^## \[([^\]]+)\](.*)$", (ROOT / "CHANGELOG.md").read_text(), re.M)
    assert headings[0] == ("Unreleased", ""), "the newest heading is [Unreleased]"
    assert headings[1] == (version, f" - {released.group(1)}"), headings[1]


def test_the_bench_extra_holds_the_modules_strol_bench_checks():
    bench = _cfg()["options.extras_require"]["bench"].split()
    assert [re.split(r"[<>=]", r)[0] for r in bench] == list(cli.BENCH_MODULES)


def test_strol_bench_without_the_bench_extra_exits_2_naming_it(monkeypatch, capsys):
    real = cli.importlib.util.find_spec
    monkeypatch.setattr(
        cli.importlib.util, "find_spec", lambda name: None if name == "tqdm" else real(name)
    )
    assert cli.main(["--help"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        "strol-bench: error: strol-bench needs the [bench] extra (tqdm not installed): "
        "pip install 'strol-gym[bench]'"
    )


def test_the_core_runs_without_the_extras_and_trains_the_same(tmp_path):
    """Importing an extra's package fails in a fresh interpreter (``sys.modules[name] = None``);
    strol_gym imports, both envs step, and ĝ's training (no progress bar) gives the losses it
    gives here."""
    from strol_gym.learners.training import train_correction

    code = f"""
import json, sys
for name in {EXTRAS_ONLY!r}:
    sys.modules[name] = None
import gymnasium as gym
import strol_gym
from strol_gym.learners.training import train_correction
for env_id in ("StROL-Robot-v0", "StROL-Highway-v0"):
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
_, history = train_correction(gym.make("StROL-Robot-v0").unwrapped.task, steps=3, batch=8)
print(json.dumps(history["loss"].tolist()))
"""
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    assert run.returncode == 0, run.stderr[-3000:]
    import gymnasium as gym

    task = gym.make("StROL-Robot-v0").unwrapped.task
    _, history = train_correction(task, steps=3, batch=8, quiet=True)
    assert np.array_equal(json.loads(run.stdout.splitlines()[-1]), history["loss"])
