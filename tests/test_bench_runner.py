"""The paired runner on the real envs: pairing, --jobs invariance, resume after interruption."""

from __future__ import annotations

import json

import numpy as np
import pytest

from strol_gym.benchmarks.engine.config import BenchConfig, paper_config
from strol_gym.benchmarks.engine.results import ResultsDir
from strol_gym.benchmarks.engine.runner import run_benchmark
from strol_gym.benchmarks.engine.worker import Worker as _Worker

GRADIENT_COPY = "strol_gym.learners.rules:GradientLearner"
"""Gradient again, by module:attr: its records must equal Gradient's if the draws are paired."""


def _tables(path):
    return {name: (path / name).read_bytes() for name in ("runs.csv", "curves.csv")}


def _records(path):
    out = {}
    for p in sorted((path / "records").glob("*.json")):
        out[p.name] = json.loads(p.read_text())["records"]
    return out


@pytest.mark.parametrize("env", ["robot", "highway"])
def test_learners_in_a_run_share_theta_star_start_and_noise(env):
    cfg = paper_config(
        [env], runs=3, learners=("gradient", GRADIENT_COPY, "one"), block=3, reference="gradient"
    )
    worker = _Worker(cfg)
    try:
        unit = cfg.units()[0]  # training condition: σ > 0, so noise is drawn every step
        recs = worker.run_unit(unit)
        theta0 = worker._envs[0].unwrapped.task.prior_modes.mean(0)
    finally:
        worker.close()
    by = {(r["seed"], r["learner"]): r for r in recs}
    for s in unit.seeds:
        g, copy, one = by[(s, "gradient")], by[(s, GRADIENT_COPY)], by[(s, "one")]
        # Same θ*, start state and first (noisy) correction for every learner of a run.
        for other in (copy, one):
            assert other["theta_star"] == g["theta_star"]
            assert other["x0"] == g["x0"]
            assert other["first_correction"] == g["first_correction"]
        # The same rule on the same draws gives the same trajectory of θ̂, noise and all.
        assert copy["errors"] == g["errors"] and copy["theta_hat"] == g["theta_hat"]
        assert len(g["errors"]) == g["steps"] + 1
        # Step 0 is θ̂0, the mean of the bimodal prior's modes.
        assert g["errors"][0] == pytest.approx(np.linalg.norm(np.array(g["theta_star"]) - theta0))
    # Different runs draw different humans.
    stars = {tuple(by[(s, "gradient")]["theta_star"]) for s in unit.seeds}
    assert len(stars) == len(unit.seeds)


@pytest.fixture(scope="module")
def small_config():
    return paper_config(
        ["highway"], runs=4, learners=("gradient", "mof"), block=2, reference="gradient"
    )


@pytest.fixture(scope="module")
def uninterrupted(small_config, tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "jobs1"
    rd = run_benchmark(small_config, out, jobs=1, quiet=True)
    from strol_gym.benchmarks.analysis.report import write_reports

    write_reports(rd, plots=False)
    return out


def test_jobs_2_gives_identical_results(small_config, uninterrupted, tmp_path):
    from strol_gym.benchmarks.analysis.report import write_reports

    rd = run_benchmark(small_config, tmp_path / "jobs2", jobs=2, quiet=True)
    write_reports(rd, plots=False)
    assert _records(tmp_path / "jobs2") == _records(uninterrupted)
    assert _tables(tmp_path / "jobs2") == _tables(uninterrupted)
    assert json.loads((tmp_path / "jobs2" / "meta.json").read_text())["status"] == "complete"


def test_resume_after_interruption_matches_uninterrupted(small_config, uninterrupted, tmp_path):
    from strol_gym.benchmarks.analysis.report import write_reports

    class Crash(Exception):
        pass

    def crash_after_three(unit, n):
        if n == 3:
            raise Crash

    out = tmp_path / "resumed"
    with pytest.raises(Crash):
        run_benchmark(small_config, out, jobs=1, quiet=True, on_unit=crash_after_three)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["status"] == "incomplete" and len(list((out / "records").glob("*.json"))) == 3
    # Also lose one finished unit, as if it had never been written.
    sorted((out / "records").glob("*.json"))[0].unlink()

    ran = []
    rd = run_benchmark(small_config, out, jobs=1, quiet=True, on_unit=lambda u, n: ran.append(u))
    assert len(ran) == len(small_config.units()) - 2  # only the missing units ran
    write_reports(rd, plots=False)
    assert _records(out) == _records(uninterrupted)
    assert _tables(out) == _tables(uninterrupted)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["status"] == "complete" and len(meta["sessions"]) == 2
    assert ResultsDir.load(out).missing_units() == []


def test_strol_with_lambda_zero_reproduces_gradient_run_for_run():
    """StROL with λ = 0 is Gradient's rule: on paired draws every number must coincide."""
    cfg = paper_config(
        ["robot"], runs=2, learners=("gradient", "strol"), block=2, reference="strol"
    )
    cfg = BenchConfig(cfg.experiments[:1], cfg.learners, "strol", 2, {"strol": {"lam": 0.0}})
    worker = _Worker(cfg)
    try:
        recs = worker.run_unit(cfg.units()[0])
    finally:
        worker.close()
    by = {(r["seed"], r["learner"]): r for r in recs}
    for s in (0, 1):
        g, st = by[(s, "gradient")], by[(s, "strol")]
        for key in ("errors", "theta_hat", "regret", "first_correction", "x0", "theta_star"):
            assert st[key] == g[key], key
