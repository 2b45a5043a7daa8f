"""The results folder: atomic unit records, config checks, corruption, --force, tables."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from strol_gym.benchmarks.analysis.report import analyse, write_reports
from strol_gym.benchmarks.engine.conditions import PAPER_LEARNERS
from strol_gym.benchmarks.engine.config import paper_config
from strol_gym.benchmarks.engine.results import ResultsDir, ResultsError


def _config(runs=4, learners=("gradient", "strol")):
    return paper_config(["robot"], runs=runs, learners=learners, block=2)


def _fake_records(config, unit, offset=0.0):
    """Synthetic records with the runner's schema (values derived from seed and learner)."""
    exp = config.experiments[unit.experiment]
    out = []
    for lr_i, learner in enumerate(config.learners):
        for s in unit.seeds:
            errs = [1.0, 0.5 + 0.1 * lr_i + 0.01 * s + offset]
            out.append(
                {
                    "env": exp.env,
                    "condition": exp.condition.name,
                    "learner": learner,
                    "seed": s,
                    "error": errs[-1],
                    "cos_error": 0.1 * errs[-1],
                    "regret": 0.3 + 0.01 * s - (0.05 + 0.01 * (s % 2) if learner == "strol" else 0),
                    "errors": errs,
                    "cos_errors": [0.1 * e for e in errs],
                    "steps": 1,
                    "terminated": False,
                    "theta_star": [0.8, -0.8],
                    "theta_hat": [0.1, 0.2],
                    "x0": [0.2, 0.2, 0.6],
                    "first_correction": [0.0, 0.0, 0.0],
                }
            )
    return out


def _fill(rd, skip=()):
    for u in rd.config.units():
        if u.key not in skip:
            rd.write_unit(u, _fake_records(rd.config, u))


def test_create_resume_and_missing_units(tmp_path):
    cfg = _config()
    rd = ResultsDir.open(tmp_path / "r", cfg)
    assert len(rd.missing_units()) == len(cfg.units()) == 8
    first = cfg.units()[0]
    rd.write_unit(first, _fake_records(cfg, first))
    again = ResultsDir.open(tmp_path / "r", cfg)  # same config: resume
    assert [u.key for u in again.missing_units()] == [u.key for u in cfg.units()[1:]]
    meta = json.loads((tmp_path / "r" / "meta.json").read_text())
    assert meta["config_hash"] == rd.config_hash and meta["status"] == "running"
    assert "numpy" in meta["versions"] and meta["seeds"]["robot/training"] == [0, 3]


def test_records_read_back_in_canonical_order(tmp_path):
    cfg = _config()
    rd = ResultsDir.open(tmp_path / "r", cfg)
    for u in reversed(cfg.units()):  # finish order must not matter
        rd.write_unit(u, list(reversed(_fake_records(cfg, u))))
    recs = rd.read_records()
    keys = [(r["condition"], r["seed"], r["learner"]) for r in recs]
    conds = [e.condition.name for e in cfg.experiments]
    expected = [(c, s, learner) for c in conds for s in range(4) for learner in cfg.learners]
    assert keys == expected


def test_mismatched_config_is_refused_until_forced(tmp_path):
    rd = ResultsDir.open(tmp_path / "r", _config())
    _fill(rd)
    with pytest.raises(ResultsError, match=r"different configuration .*runs: 4 vs 5"):
        ResultsDir.open(tmp_path / "r", _config(runs=5))
    assert len(rd.read_records()) == 4 * 4 * 2  # untouched
    fresh = ResultsDir.open(tmp_path / "r", _config(runs=5), force=True)
    assert len(fresh.missing_units()) == 12 and not list((tmp_path / "r" / "records").iterdir())


def test_foreign_or_corrupt_folders(tmp_path):
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("precious")
    for force in (False, True):
        with pytest.raises(ResultsError, match="not a strol-bench results folder"):
            ResultsDir.open(foreign, _config(), force=force)
    assert (foreign / "thesis.tex").read_text() == "precious"

    rd = ResultsDir.open(tmp_path / "r", _config())
    _fill(rd)
    unit = rd.config.units()[3]
    rd.record_path(unit).write_text('{"config_hash": "')  # a torn or edited file
    with pytest.raises(ResultsError, match="corrupt"):
        rd.read_records()
    rd.write_unit(unit, _fake_records(rd.config, unit)[:-1])  # a run missing
    with pytest.raises(ResultsError, match="exactly its unit's runs"):
        rd.read_records()
    (tmp_path / "r" / "meta.json").write_text("{")
    with pytest.raises(ResultsError, match="corrupt"):
        ResultsDir.open(tmp_path / "r", _config())


def test_tables_and_summary(tmp_path):
    rd = ResultsDir.open(tmp_path / "r", _config(runs=6, learners=PAPER_LEARNERS))
    _fill(rd)
    a, plots = write_reports(rd, plots=False)
    assert plots == []
    with open(tmp_path / "r" / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert {"env", "condition", "learner", "metric", "mean", "std", "sem", "n"} <= set(rows[0])
    assert len(rows) == 4 * 5 * 3  # conditions × learners × metrics
    grad = next(r for r in rows if r["learner"] == "gradient" and r["metric"] == "error")
    errs = 0.5 + 0.01 * np.arange(6)
    assert float(grad["mean"]) == pytest.approx(errs.mean())
    assert float(grad["sem"]) == pytest.approx(errs.std(ddof=1) / math.sqrt(6))
    with open(tmp_path / "r" / "stats.csv") as f:
        stats_rows = list(csv.DictReader(f))
    need = {"env", "condition", "metric", "learner", "baseline", "p_holm", "p_raw", "statistic"}
    assert need <= set(stats_rows[0]) and len(stats_rows) == 4 * 3 * 4
    # StROL's regret is 0.05 or 0.06 below every baseline's in every run.
    reg = [r for r in stats_rows if r["metric"] == "regret"]
    assert all(float(r["mean_diff"]) == pytest.approx(-0.055) for r in reg)
    assert all(float(r["p_holm"]) < 1e-4 for r in reg)  # t ≈ −24.6 on 5 df
    h1 = [v for v in a.verdicts if v["hypothesis"] == "H1"]
    assert len(h1) == 1 and h1[0]["holds"]  # lower than every baseline on regret
    md = (tmp_path / "r" / "summary.md").read_text()
    assert "H1 robot / training (regret): HOLDS" in md and "StROL lower than Gradient" in md
    assert "1 − cos" in md and "‖θ* − θ̂‖₂" in md
    with open(tmp_path / "r" / "curves.csv") as f:
        assert len(list(csv.DictReader(f))) == 4 * 6 * 5 * 2
    assert analyse(rd.config, rd.read_records()).summary == a.summary


def test_heavy_tail_statistics_in_every_summary(tmp_path):
    rd = ResultsDir.open(tmp_path / "r", _config(runs=6, learners=PAPER_LEARNERS))
    _fill(rd)
    a, _ = write_reports(rd, plots=False, resamples=100)
    first = (tmp_path / "r" / "summary.csv").read_bytes()
    with open(tmp_path / "r" / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    grad = next(r for r in rows if r["learner"] == "gradient" and r["metric"] == "error")
    # 6 runs: the IQM cuts one from each end -> mean(0.51, 0.52, 0.53, 0.54)
    assert float(grad["iqm"]) == pytest.approx(0.525)
    assert float(grad["iqm_ci95_low"]) <= 0.525 <= float(grad["iqm_ci95_high"])
    with open(tmp_path / "r" / "stats.csv") as f:
        stats_rows = list(csv.DictReader(f))
    reg = [r for r in stats_rows if r["metric"] == "regret"]
    # StROL's regret is below every baseline's in every run: P = 1 with a degenerate interval.
    assert all(float(r["prob_improvement"]) == 1.0 for r in reg)
    assert all(float(r["prob_improvement_ci95_low"]) == 1.0 for r in reg)
    assert all(r["mark"] == "↓***" for r in reg)
    md = (tmp_path / "r" / "summary.md").read_text()
    assert "IQM [95 % CI] of regret" in md and "P(StROL better in a run) [95 % CI]" in md
    assert "| all 4 (n = 24) |" in md and "↓ = StROL significantly lower" in md
    # every run's matrix is kept for the figures; the bootstrap is seeded: same bytes again
    assert a.runs[("robot", "training", "regret")].shape == (6, 5)
    write_reports(rd, plots=False, resamples=100)
    assert (tmp_path / "r" / "summary.csv").read_bytes() == first


def test_no_verdicts_unless_the_config_is_the_papers(tmp_path):
    """H1/H2 speak of the paper's five learners in the paper's conditions: a subset gets
    tables and tests but no verdict lines."""
    rd = ResultsDir.open(tmp_path / "r", _config(runs=6, learners=("gradient", "one", "strol")))
    _fill(rd)
    a, _ = write_reports(rd, plots=False)
    assert a.verdicts == []
    assert "H1" not in (tmp_path / "r" / "summary.md").read_text()
    assert len(a.posthoc) > 0


def test_changed_code_or_weights_block_resume(tmp_path):
    ResultsDir.open(tmp_path / "r", _config(), extra={"code": "aaa", "learners": {"w": 1}})
    with pytest.raises(ResultsError, match=r"strol-gym code .* has changed"):
        ResultsDir.open(tmp_path / "r", _config(), extra={"code": "bbb", "learners": {"w": 1}})
    with pytest.raises(ResultsError, match="learner's class, settings or weights changed"):
        ResultsDir.open(tmp_path / "r", _config(), extra={"code": "aaa", "learners": {"w": 2}})
    ResultsDir.open(tmp_path / "r", _config(), extra={"code": "aaa", "learners": {"w": 1}})


def _record_versions(path, **changed):
    """Edit the versions a results folder says it was made with (as another install would
    have recorded them)."""
    meta = json.loads((path / "meta.json").read_text())
    meta["versions"].update(changed)
    (path / "meta.json").write_text(json.dumps(meta))


@pytest.mark.parametrize(
    "package", ["numpy", "scipy", "torch", "gymnasium", "mujoco", "highway-env"]
)
def test_resume_under_other_versions_warns_and_is_refused_until_forced(tmp_path, capsys, package):
    rd = ResultsDir.open(tmp_path / "r", _config())
    _fill(rd)
    assert rd.meta["versions"][package]  # the folder records what it ran with
    _record_versions(tmp_path / "r", **{package: "0.0.1"})
    with pytest.raises(ResultsError, match=rf"other package versions \({package} 0\.0\.1 -> "):
        ResultsDir.open(tmp_path / "r", _config())
    assert f"warning: {tmp_path / 'r'} was made under other package versions" in (
        capsys.readouterr().err
    )
    assert len(rd.read_records()) == 4 * 4 * 2  # untouched
    fresh = ResultsDir.open(tmp_path / "r", _config(), force=True)
    assert len(fresh.missing_units()) == 8 and fresh.meta["versions"][package] != "0.0.1"


def test_versions_that_do_not_shape_records_do_not_block_a_resume(tmp_path, capsys):
    rd = ResultsDir.open(tmp_path / "r", _config())
    _fill(rd)
    _record_versions(tmp_path / "r", matplotlib="0.0.1", **{"stable-baselines3": "0.0.1"})
    assert not ResultsDir.open(tmp_path / "r", _config()).missing_units()
    assert "package versions" not in capsys.readouterr().err


def test_cli_resume_under_other_versions_exits_2_until_forced(tmp_path, capsys):
    from cli_checks import cli_error
    from strol_gym.benchmarks import cli

    out = tmp_path / "r"
    argv = ["run", "--env", "robot", "--runs", "1", "--corrections", "1", "--quiet"]
    argv += ["--no-plots", "--learners", "gradient", "--jobs", "1", "--out", str(out)]
    assert cli.main(argv) in (0, None)
    _record_versions(out, mujoco="0.0.1")
    line = cli_error(argv, capsys)
    assert "mujoco 0.0.1 -> " in line and "--force" in line
    assert cli.main([*argv, "--force"]) in (0, None)
    assert json.loads((out / "meta.json").read_text())["versions"]["mujoco"] != "0.0.1"
