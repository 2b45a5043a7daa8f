"""strol-bench argument checking: bad input fails with status 2 before any work starts."""

from __future__ import annotations

import json
import sys

import pytest

from strol_gym.benchmarks import cli
from strol_gym.benchmarks.engine.conditions import Condition, env_preset, paper_condition
from strol_gym.benchmarks.engine.config import BenchConfig, Experiment, paper_config


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["run", "--env", "robot", "--learners", "gradient,nope"], "unknown learner 'nope'"),
        (["run", "--env", "robot", "--learners", "no_such_mod:thing"], "cannot import"),
        (["run", "--env", "robot", "--sigma", "-0.1"], "--sigma must be a number in [0, 100]"),
        (["run", "--env", "robot", "--sigma", "nan"], "--sigma must be a number in [0, 100]"),
        (["run", "--env", "robot", "--condition", "windy"], "unknown condition 'windy'"),
        (
            ["run", "--env", "boat"],
            "env must be one of ['highway', 'robot', 'study1', 'study1-v1', 'study1-v2', "
            "'study2', 'study2-v1', 'study2-v2', 'study3', 'study3-v1', 'study3-v2'], got 'boat'",
        ),
        (["paper", "--runs", "0"], "--runs must be an integer in [1, "),
        (["paper", "--jobs", "0"], "--jobs must be an integer >= 1"),
        (["paper", "--env", "moon"], "invalid choice: 'moon'"),
        (
            ["run", "--env", "robot", "--condition", "clean", "--sigma", "0.1"],
            "--condition cannot be combined",
        ),
        (
            ["run", "--env", "robot", "--learners", "gradient,one", "--reference", "strol"],
            "reference",
        ),
        (
            ["run", "--env", "robot", "--learner-kwargs", "{bad json"],
            "--learner-kwargs must be JSON",
        ),
    ],
)
def test_bad_arguments_exit_2_before_work(argv, message, tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        cli.main([*argv, "--out", str(out), "--quiet"])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_list_names_everything(capsys):
    assert cli.main(["list"]) == 0
    text = capsys.readouterr().out
    for word in ("StROL-Robot-v0", "StROL-Highway-v0", "gradient", "strol", "noisy-biased"):
        assert word in text


def test_paper_conditions_follow_design_table():
    robot, highway = env_preset("robot"), env_preset("highway")
    assert (robot.runs, robot.n_corrections, robot.training_sigma) == (100, 5, 0.25)
    assert (highway.runs, highway.n_corrections, highway.training_sigma) == (250, 10, 0.10)
    assert paper_condition("robot", "training") == Condition("training", 0.25, 0.0, "bimodal")
    assert paper_condition("highway", "noisy-biased") == Condition(
        "noisy-biased", 0.5, 0.5, human="driver"
    )
    assert paper_condition("robot", "uniform-prior").prior == "uniform"
    assert paper_condition("highway", "uniform-prior").sigma == 0.10
    assert paper_condition("robot", "clean").env_kwargs() == {
        "prior": "bimodal",
        "person": {"sigma": 0.0, "bias": 0.0},
    }
    with pytest.raises(ValueError, match="condition must be one of"):
        paper_condition("robot", "windy")
    with pytest.raises(ValueError, match="sigma"):
        Condition("x", sigma=-1.0)


def test_config_round_trip_and_units():
    cfg = paper_config(["robot", "highway"], runs=7, block=3)
    assert len(cfg.experiments) == 8
    again = BenchConfig.from_dict(cfg.to_dict())
    assert again.to_dict() == cfg.to_dict() and again.hash() == cfg.hash()
    units = cfg.units()
    assert [u.seeds for u in units[:3]] == [(0, 1, 2), (3, 4, 5), (6,)]
    assert len(units) == 8 * 3
    exp = Experiment("robot", paper_condition("robot", "clean"), runs=2, seed=5)
    assert list(exp.seeds) == [5, 6] and exp.env_kwargs()["max_episode_steps"] == 5
    with pytest.raises(ValueError, match=r"runs must be an integer in \[1, "):
        Experiment("robot", paper_condition("robot", "clean"), runs=0)


PLUGIN_EXPERIMENT = """
from strol_gym.benchmarks.args import positive_int
from strol_gym.benchmarks.experiments import register_experiment
from strol_gym.benchmarks.experiments.base import BenchExperiment, Outcome


class Squares(BenchExperiment):
    help = "squares of 1..n"
    columns = ("k", "square")

    def add_arguments(self, p):
        p.add_argument("--n", type=positive_int("--n"), default=3)
        p.add_argument("--out", default=None)
        p.add_argument("--no-plots", action="store_true")

    def plan(self, args):
        if args.n > 5:
            raise ValueError(f"--n must be at most 5, got {args.n}")
        return list(range(1, args.n + 1))

    def execute(self, ks, args, out):
        rows = [{"k": k, "square": k * k} for k in ks]
        md = [f"{r['k']}^2 = {r['square']}" for r in rows]
        return Outcome(out, md, rows, meta={"n": args.n})


register_experiment("squares-test", Squares)
"""


def test_an_experiment_of_ones_own_is_one_plugin_file(tmp_path, capsys):
    from strol_gym.benchmarks.experiments import EXPERIMENTS

    plugin = tmp_path / "squares_plugin.py"
    plugin.write_text(PLUGIN_EXPERIMENT)
    out = tmp_path / "sq"
    try:
        code = cli.main(["squares-test", "--plugin", str(plugin), "--n", "4", "--out", str(out)])
        assert code == 0
        printed = capsys.readouterr().out
        assert "4^2 = 16" in printed
        assert (out / "squares-test.csv").read_text().splitlines() == [
            "k,square",
            "1,1",
            "2,4",
            "3,9",
            "4,16",
        ]
        meta = json.loads((out / "squares-test.json").read_text())
        assert meta["preset"] == "squares-test" and meta["n"] == 4 and "versions" in meta
        # the plan's ValueError is a usage error: exit status 2, the message, no folder
        with pytest.raises(SystemExit) as e:
            cli.main(["squares-test", "--plugin", str(plugin), "--n", "9", "--out", str(out / "x")])
        assert e.value.code == 2
        assert "--n must be at most 5, got 9" in capsys.readouterr().err
        assert not (out / "x").exists()
    finally:
        if "squares-test" in EXPERIMENTS:
            EXPERIMENTS.unregister("squares-test")
        sys.modules.pop("squares_plugin", None)


@pytest.mark.parametrize("argv", [["list"], ["--help"], ["paper", "--help"]])
def test_output_into_a_closed_pipe_ends_quietly(argv):
    """``strol-bench list | head``: the reader leaves early; no broken-pipe message, status 0."""
    import os
    import subprocess
    import sys

    read, write = os.pipe()
    os.close(read)
    try:
        cmd = [sys.executable, "-m", "strol_gym.benchmarks", *argv]
        done = subprocess.run(cmd, stdout=write, stderr=subprocess.PIPE, timeout=120)
    finally:
        os.close(write)
    assert done.returncode == 0
    assert done.stderr.decode() == ""


def test_the_listing_gives_each_own_command_the_help_its_parser_gives():
    """``strol-bench --help`` names the commands that are not experiments from
    ``cli.OWN_COMMANDS`` (without importing them): the same words their full parsers give."""
    full = cli.build_parser()  # every parser in full
    (sub,) = [a for a in full._actions if a.dest == "command"]
    helps = {a.dest: a.help for a in sub._choices_actions}
    assert {name: helps.get(name) for name in cli.OWN_COMMANDS} == cli.OWN_COMMANDS


@pytest.mark.parametrize("argv", [["--help"], ["list"], ["paper", "--help"]])
def test_help_and_list_load_no_heavy_stack(argv):
    """The start-up of ``--help`` and ``list`` (lab/speed/cli_start.py times it) imports
    neither torch, scipy, MuJoCo nor matplotlib: checked in a fresh interpreter."""
    import subprocess

    code = (
        "import contextlib, io, sys\n"
        "from strol_gym.benchmarks.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
        f"    main({argv!r})\n"
        "heavy = ('torch', 'scipy', 'mujoco', 'matplotlib', 'highway_env', 'safetensors')\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & set(heavy)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
