"""``strol-bench robustness``: learners × correction models × σ, from the CLI (tiny runs on
diagnostic seeds), its config and its marks."""

from __future__ import annotations

import csv
import json

import pytest
from cli_checks import cli_error
from strol_gym.benchmarks import cli
from strol_gym.benchmarks.experiments import robustness

from strol_gym.humans import HUMAN_MODELS

SEED = 1000  # the diagnostics seed range


def test_writes_heat_map_csv_and_markdown(tmp_path, capsys):
    out = tmp_path / "rob"
    argv = ["robustness", "--env", "robot", "--runs", "3", "--block", "3", "--jobs", "1"]
    argv += ["--humans", "nominal,skipping,late", "--sigmas", "0.25,0.5"]
    argv += ["--learners", "gradient,strol", "--seed", str(SEED), "--quiet", "--out", str(out)]
    assert cli.main(argv) == 0
    text = capsys.readouterr().out
    assert "wall time" in text and "σ = 0.25" in text and "σ = 0.5" in text
    for name in ("robustness.csv", "robustness.md", "robustness.json", "plots/robustness.png"):
        assert (out / name).is_file(), name
    rows = list(csv.DictReader((out / "robustness.csv").open()))
    cells = {(r["human"], float(r["sigma"]), r["learner"]) for r in rows}
    assert cells == {
        (h, s, learner)
        for h in ("nominal", "skipping", "late")
        for s in (0.25, 0.5)
        for learner in ("gradient", "strol")
    }
    assert all(r["metric"] == "regret" and r["n"] == "3" for r in rows)
    # StROL is the reference: no test against itself; the baseline's cell has its p-value
    assert all(r["p_t_holm"] == "" for r in rows if r["learner"] == "strol")
    assert all(r["p_t_holm"] != "" for r in rows if r["learner"] == "gradient")
    meta = json.loads((out / "robustness.json").read_text())
    assert meta["humans"] == ["nominal", "skipping", "late"] and meta["sigmas"] == [0.25, 0.5]
    md = (out / "robustness.md").read_text()
    assert "| learner | nominal | skipping | late |" in md


def test_default_config_is_every_human_at_two_noise_levels():
    config = robustness.make_config("robot")
    names = [e.condition.human for e in config.experiments]
    assert names == list(HUMAN_MODELS) * 2
    assert sorted({e.condition.sigma for e in config.experiments}) == [0.25, 0.5]
    assert config.learners == ("gradient", "one", "mof", "e2e", "strol")
    assert {e.runs for e in config.experiments} == {robustness.DEFAULT_RUNS["robot"]}
    # the timing models' windows follow the episode's corrections
    kw = {e.condition.human: e.condition.human_kwargs for e in config.experiments}
    assert kw["early"] == {"until": 2} and kw["late"] == {"start": 3}
    hw = robustness.make_config("highway", humans=["early", "late"], sigmas=[0.1])
    assert [e.condition.human_kwargs for e in hw.experiments] == [{"until": 4}, {"start": 6}]


def test_mark_reads_the_holm_corrected_paired_test():
    base = {"mean_diff": -0.2, "hodges_lehmann": -0.1, "wilcoxon_p_holm": 0.5}
    assert robustness.mark({**base, "p_holm": 0.004}) == "↓**"  # StROL lower: baseline worse
    assert robustness.mark({**base, "mean_diff": 0.2, "p_holm": 0.03}) == "↑*"
    assert robustness.mark({**base, "p_holm": 0.2}) == ""
    assert robustness.mark(None) == ""


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--humans", "nobody"], "nobody"),
        (["--learners", "gradient,one"], "--learners must include 'strol'"),
        (["--sigmas", "-1"], "--sigmas must be comma-separated finite numbers >= 0"),
        (["--sigmas", "200"], "--sigmas must be a number in"),
        (["--runs", "0"], "--runs must be an integer in [1,"),
        (["--env", "study1"], "invalid choice: 'study1'"),
    ],
)
def test_bad_input_exits_2_before_any_folder(argv, message, tmp_path, capsys):
    out = tmp_path / "out"
    assert message in cli_error(["robustness", *argv, "--out", str(out)], capsys)
    assert not out.exists()
