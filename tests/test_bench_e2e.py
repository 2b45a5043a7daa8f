"""The fast preset end to end through the CLI: both envs, every output file, the summary."""

from __future__ import annotations

import csv
import json

from strol_gym.benchmarks import cli
from strol_gym.benchmarks.engine.conditions import PAPER_TABLE_LEARNERS, REFERENCE_LEARNER
from strol_gym.benchmarks.engine.kernels import float_kernels, kernel_label


def test_fast_paper_preset_end_to_end(tmp_path, capsys):
    out = tmp_path / "paper"
    argv = ["paper", "--env", "all", "--runs", "3", "--block", "3", "--jobs", "1", "--quiet"]
    assert cli.main([*argv, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "StROL-Robot-v0: Regret" in printed and "StROL-Highway-v0: Error" in printed
    assert "H1 robot/training (regret)" in printed and "H1 highway/training (error)" in printed
    assert f"plot: {out / 'plots' / 'fig4.png'}" in printed

    meta = json.loads((out / "meta.json").read_text())
    assert meta["status"] == "complete" and meta["git"] is not None
    assert set(meta["extra"]["learners"]["robot"]) == set(PAPER_TABLE_LEARNERS)
    assert "e2e-scratch" in PAPER_TABLE_LEARNERS  # the paper's e2e beside the bounded one
    assert "checkpoint_sha256" in meta["extra"]["learners"]["highway"]["strol"]
    assert meta["kernels"] == float_kernels()
    for unit in (out / "records").glob("*.json"):
        assert json.loads(unit.read_text())["kernels"] == kernel_label()

    with open(out / "runs.csv") as f:
        runs = list(csv.DictReader(f))
    assert len(runs) == 2 * 4 * 3 * 6  # envs × conditions × runs × learners
    robot = [r for r in runs if r["env"] == "robot"]
    assert all(r["regret"] != "nan" for r in robot) and "error_step_5" in runs[0]
    highway = [r for r in runs if r["env"] == "highway"]
    assert all(r["regret"] == "nan" for r in highway)

    with open(out / "summary.csv") as f:
        summary = list(csv.DictReader(f))
    metrics = {(r["env"], r["metric"]) for r in summary}
    assert ("robot", "regret") in metrics and ("highway", "error") in metrics
    assert ("highway", "regret") not in metrics
    with open(out / "stats.csv") as f:
        stats = list(csv.DictReader(f))
    assert {r["baseline"] for r in stats} == set(PAPER_TABLE_LEARNERS) - {REFERENCE_LEARNER}
    assert all(r["learner"] == "strol" for r in stats)
    for stem in ("fig4", "bars_error", "bars_cos_error", "bars_regret", "curves_error"):
        for ext in ("png", "svg"):
            assert (out / "plots" / f"{stem}.{ext}").stat().st_size > 1000
    md = (out / "summary.md").read_text()
    assert "## Hypotheses" in md and "repeated-measures ANOVA" in md

    # Rerunning the finished command does no work and reports the same tables.
    before = (out / "runs.csv").read_bytes()
    assert cli.main([*argv, "--out", str(out), "--no-plots"]) == 0
    assert (out / "runs.csv").read_bytes() == before
    assert cli.main(["report", str(out), "--no-plots"]) == 0
    assert (out / "runs.csv").read_bytes() == before
