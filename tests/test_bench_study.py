"""strol-bench study: bad input exits 2 before any folder exists; a 2-user run of Task 1 writes
its table (CSV + markdown), meta JSON, verdicts and plot, and resumes without rerunning."""

from __future__ import annotations

import csv
import json
import math

import pytest
from cli_checks import cli_error

from strol_gym.benchmarks import cli
from strol_gym.benchmarks.engine.kernels import float_kernels
from strol_gym.benchmarks.experiments.study import METRICS
from strol_gym.tasks import make_task


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--task", "4"], "--task must be a comma-separated list of Task numbers from 1,2,3"),
        (["--task", "1,0"], "--task must be"),
        (["--task", "one"], "--task must be"),
        (["--task", ","], "--task must be"),
        (["--users", "0"], "--users must be an integer in [1, "),
        (["--users", "-3"], "--users must be an integer in [1, "),
        (["--jobs", "0"], "--jobs must be an integer >= 1"),
    ],
)
def test_study_bad_input_exits_2_before_any_folder(argv, message, tmp_path, capsys):
    out = tmp_path / "out"
    assert message in cli_error(["study", *argv, "--out", str(out), "--quiet"], capsys)
    assert not out.exists()


def test_study_defaults_to_v2_with_the_fitted_population():
    import argparse

    from strol_gym.benchmarks.experiments.study import Study
    from strol_gym.learners.registry import make_learner

    p = argparse.ArgumentParser()
    Study().add_arguments(p)
    config = Study().plan(p.parse_args([]))
    assert [e.env for e in config.experiments] == ["study1-v2", "study2-v2", "study3-v2"]
    assert {e.env_id for e in config.experiments} == {"StROL-Study-v2"}
    assert all("person" not in e.env_kwargs() for e in config.experiments)  # v2's default
    assert all(p == {"name": "fitted"} for p in config.persons().values())
    # v1 keeps its hand-set participant; the fitted one exists on v2 only
    v1 = Study().plan(p.parse_args(["--env-version", "v1"]))
    assert [e.env for e in v1.experiments] == ["study1-v1", "study2-v1", "study3-v1"]
    assert all(p["name"] == "observer" for p in v1.persons().values())
    with pytest.raises(SystemExit) as e:
        Study().plan(p.parse_args(["--env-version", "v1", "--participant", "fitted"]))
    assert e.value.code == 2
    # v1's study Tasks find the ĝ trained for v1; v0's keep the published ones
    for k in (1, 2, 3):
        task = v1.experiments[k - 1].env_kwargs()["task"]
        for kind in ("strol", "e2e"):
            v1_path = make_learner(kind, task=make_task(task)).checkpoint
            v0 = make_learner(kind, task=make_task(f"study-task{k}")).checkpoint
            assert make_task(task).task_id == f"StROL-Study-v1-task{k}"
            assert v1_path.endswith(f"study{k}-v1_{kind}.safetensors")
            assert v0.endswith(f"study{k}_{kind}.safetensors")


def test_study_two_users_writes_table_meta_plot_and_resumes(tmp_path, capsys):
    # v0 (the published results): deprecated, warned on the command line
    out = tmp_path / "study"
    argv = ["study", "--task", "1", "--users", "2", "--jobs", "1", "--out", str(out), "--quiet"]
    argv += ["--env-version", "v0"]
    assert cli.main(argv) == 0
    captured = capsys.readouterr()
    printed = captured.out
    assert "Task 1: H3" in printed and "wall time" in printed
    assert "StROL-Study-v0 is deprecated" in captured.err

    meta = json.loads((out / "meta.json").read_text())
    assert meta["status"] == "complete" and meta["kernels"] == float_kernels()
    exps = meta["config"]["experiments"]
    assert [(e["env"], e["runs"], e["seed"]) for e in exps] == [("study1", 2, 20000)]

    rows = list(csv.DictReader(open(out / "study_table.csv")))
    learners = ["gradient", "one", "mof", "e2e", "strol"]
    assert [(r["metric"], r["learner"]) for r in rows] == [
        (m, learner) for m in METRICS for learner in learners
    ]
    for r in rows:
        assert math.isfinite(float(r["task1_mean"])) and int(r["all_n"]) == 2
    # the published numbers sit beside the authors'-way rows only (they were computed that way)
    paper = {(r["metric"], r["learner"]): r["paper_mean"] for r in rows}
    assert float(paper[("regret_authors", "strol")]) == 1.03
    assert float(paper[("correction_time_authors", "one")]) == 2.5
    assert math.isnan(float(paper[("regret", "strol")]))

    md = (out / "study_table.md").read_text()
    assert "| Regret (ours, eq. S1) | StROL |" in md and "| Regret (authors' way) | StROL |" in md
    assert "Task 1: H3" in md and "no like-for-like number" in md
    assert "## H3 pooled the paper's way" in md and "over One, MOF, StROL: F(" in md
    pooled = json.loads((out / "study.json").read_text())["pooled"]
    assert [p["metric"] for p in pooled] == [
        "regret",
        "regret_authors",
        "correction_time",
        "correction_time_authors",
    ]
    assert all(p["n"] == 2 and len(p["pairs"]) == 3 for p in pooled)
    assert (out / "plots" / "study.png").stat().st_size > 0
    verdicts = json.loads((out / "study.json").read_text())["verdicts"]
    assert [v["task"] for v in verdicts] == [1] and len(verdicts[0]["details"]) == 4

    # paired: every learner saw both user seeds; the env's correction totals are recorded
    recs = [
        r
        for p in sorted((out / "records").glob("*.json"))
        for r in json.loads(p.read_text())["records"]
    ]
    assert sorted((r["learner"], r["seed"]) for r in recs) == sorted(
        (learner, s) for learner in learners for s in (20000, 20001)
    )
    for r in recs:
        assert r["steps"] == 1200 and (r["corrections"] >= 1) == (r["correction_time"] > 0)
        # the authors' count logs at most one sample per 0.05 s tick of a correction
        assert 0.0 <= r["correction_time_authors"] <= r["correction_time"] + 1e-9
        assert (r["correction_time_authors"] > 0) == (r["corrections"] >= 1)
    # user 20000 pushes; user 20001's θ̂0 already plans with regret 0 under θ*: satisfied at once
    assert all(r["corrections"] >= 1 for r in recs if r["seed"] == 20000)
    assert all(r["corrections"] == 0 for r in recs if r["seed"] == 20001)

    # resume: the same command runs no unit again
    assert cli.main(argv) == 0
    meta = json.loads((out / "meta.json").read_text())
    assert [s["units_run"] for s in meta["sessions"]] == [1, 0]
