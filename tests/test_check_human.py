"""strol-bench check-human on synthetic sessions in the authors' layout (written here), and its
joint band."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_checks import cli_error

from strol_gym.benchmarks import cli
from strol_gym.benchmarks.sessions.check_human import (
    STATISTICS,
    StudyPopulation,
    by_task,
    joint_band,
    judge,
    logged_plan,
    min_draws,
    nearest_states,
    person_from,
    reacting_sessions,
    read_sessions,
    statistics,
    two_sided_p,
)


@pytest.fixture(scope="module")
def logs(authors_tree, tmp_path_factory):
    """Three people × Tasks 1-3 × every learner, two corrections each (StROL's one); imported."""
    root = authors_tree(people=3, seed=49, sizes=(3, 4), ours_sizes=(3,))
    out = tmp_path_factory.mktemp("logs") / "logs"
    assert cli.main(["import-study", str(root), "--out", str(out)]) == 0
    return out


def test_joint_band_holds_its_level():
    """Fresh replicates of the same person fall outside some band about 5 % of the time, where
    twelve marginal 95 % bands would miss far more often."""
    rng = np.random.default_rng(0)
    cov = 0.5 * np.eye(12) + 0.5  # correlated checks
    draws = rng.multivariate_normal(np.zeros(12), cov, 4000)
    gamma, bands = joint_band(draws)
    fresh = rng.multivariate_normal(np.zeros(12), cov, 4000)
    outside = ((fresh < bands[:, 0]) | (fresh > bands[:, 1])).any(axis=1).mean()
    assert 0.03 < outside < 0.075
    assert (1 - 0.95) / 12 < gamma < 0.05  # between Bonferroni's and no adjustment
    marginal = np.quantile(draws, [0.025, 0.975], axis=0).T
    assert ((fresh < marginal[:, 0]) | (fresh > marginal[:, 1])).any(axis=1).mean() > 0.15


def test_a_real_value_like_the_replicates_fails_at_most_5_percent_of_the_time():
    """Exact, whatever the values: of a pool of 220 exchangeable rows, each taken in turn as
    the real value against the other 219, at most ⌊0.05·220⌋ = 11 fail some check. (Ranking
    the real value among the replicates alone while each replicate counts itself failed 20:
    near γ's floor the real value needed one more replicate beyond it.)"""
    pool = np.random.default_rng(0).standard_normal((220, 5))
    failed = 0
    for i in range(len(pool)):
        gamma, bands, p = judge(np.delete(pool, i, axis=0), pool[i])
        failed += bool((p < gamma).any())
        inside = (pool[i] >= bands[:, 0]) & (pool[i] <= bands[:, 1])
        assert np.array_equal(inside, p >= gamma)  # the band says what p says
    assert 0 < failed <= 11


def test_min_draws_lets_a_value_beyond_every_replicate_fail():
    assert (min_draws(27), min_draws(15), min_draws(15, 0.8)) == (1079, 599, 149)
    for s in (min_draws(5), 260):
        reps = np.random.default_rng(1).standard_normal((s, 5))
        real = np.median(reps, axis=0)
        real[2] = reps[:, 2].max() + 1.0
        gamma, _, p = judge(reps, real)
        assert p[2] < gamma and (np.delete(p, 2) >= gamma).all()


def test_person_from_a_class_builds_one():
    assert isinstance(person_from(f"{StudyPopulation.__module__}:StudyPopulation"), StudyPopulation)


def test_two_sided_p():
    d = np.arange(100.0)
    assert two_sided_p(d, 49.5)[0] == pytest.approx(1.0)
    assert two_sided_p(d, -1.0)[0] == 0.0
    assert two_sided_p(d, 0.0)[0] == pytest.approx(0.02)


def test_real_statistics_count_by_learner(logs):
    tasks = by_task(read_sessions(logs))
    assert sorted(tasks) == [1, 2, 3]
    s = statistics(tasks[2])
    assert s["count_one"] == s["count_mof"] == 2.0 and s["count_strol"] == 1.0
    assert 0.0 <= s["raised"] <= 1.0 and s["size_median"] > 0
    assert set(s) == set(STATISTICS)


def test_check_human_writes_report_figure_and_replicates(logs, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["check-human", str(logs), "--human", "fitted-aimed", "--out", str(out)]
    assert cli.main([*argv, "--draws", "40", "--level", "0.2", "--keep", "2"]) == 0
    assert "check-human: fitted-aimed" in capsys.readouterr().out
    report = json.loads((out / "report.json").read_text())
    assert len(report["checks"]) == 3 * len(STATISTICS)
    counts = [c for c in report["checks"] if c["statistic"].startswith("count_")]
    assert all(c["pass"] is None and "not simulated" in c["note"] for c in counts)
    sized = [c for c in report["checks"] if c["statistic"] == "size_median"]
    assert all(isinstance(c["pass"], bool) and len(c["band"]) == 2 for c in sized)
    assert report["band"]["checks"] == 3 * 5
    assert report["band"]["level"] == 0.2 and report["band"]["min_draws"] == 37
    assert (out / "check.png").stat().st_size > 0 and (out / "report.md").exists()
    # the kept replicate's logs give back its statistics
    again = by_task(read_sessions(out / "sessions" / "draw_001"))
    for t, sessions in again.items():
        redo = statistics(sessions)
        kept = report["kept_replicates"][1][str(t)]
        for k in ("size_median", "size_small", "angle_median", "raised"):
            assert redo[k] == pytest.approx(kept[k], rel=1e-9), (t, k)
    # same seed, same report
    out2 = tmp_path / "out2"
    argv2 = ["check-human", str(logs), "--human", "fitted-aimed", "--out", str(out2)]
    assert cli.main([*argv2, "--draws", "40", "--level", "0.2", "--keep", "0", "--no-plots"]) == 0
    assert json.loads((out2 / "report.json").read_text())["checks"] == report["checks"]


def test_nearest_states_pairs_a_simulated_time_with_the_logged_state_there():
    a, b, c = ({"x": k} for k in "abc")
    states = [(0.0, a), (0.5, b), (1.0, c)]
    got = nearest_states(states, np.array([0.1, 0.25, 0.3, 0.75, 0.9]))
    assert [g["x"] for g in got] == ["a", "a", "b", "b", "c"]  # 0.25 and 0.75: ties, the earlier
    unplaced = [(float("nan"), a), (float("nan"), b)]  # no path sample: taken in turn
    assert [g["x"] for g in nearest_states(unplaced, np.array([0.9, 0.1, 0.5]))] == ["a", "b", "a"]
    mixed = [(float("nan"), a), (0.8, c)]
    assert [g["x"] for g in nearest_states(mixed, np.array([0.0]))] == ["c"]


def test_population_simulates_the_counts(logs, tmp_path):
    out = tmp_path / "pop"
    argv = ["check-human", str(logs), "--population", "--out", str(out), "--draws", "70"]
    assert cli.main([*argv, "--level", "0.2", "--keep", "1", "--no-plots"]) == 0
    report = json.loads((out / "report.json").read_text())
    counts = [c for c in report["checks"] if c["statistic"].startswith("count_")]
    assert all(isinstance(c["pass"], bool) for c in counts)
    when = [c for c in report["checks"] if c["statistic"] == "when_median"]
    assert when and all(isinstance(c["pass"], bool) for c in when)  # its timing hazard decides
    # the kept replicate's logs give back its counts and timing (Task 1's sessions end where
    # the person's corrections end them: their logged length is the simulated one)
    again = by_task(read_sessions(out / "sessions" / "draw_000"))
    for t, sessions in again.items():
        redo, kept = statistics(sessions), report["kept_replicates"][0][str(t)]
        for k in ("count_one", "count_strol", "when_median"):
            assert redo[k] == pytest.approx(kept[k], rel=1e-12, nan_ok=True), (t, k)


def test_population_reuses_its_aims_and_plans_bit_for_bit(logs):
    """A replicate from the aims and plans computed once per session is the one computed
    afresh at the picked states (the aim is row by row); one Task object per logged Task."""
    from strol_gym.envs.study.population import shipped

    real = read_sessions(logs)
    assert len({id(s.task) for s in real}) == len({s.number for s in real}) == 3
    ss = by_task(real)[2]
    person = StudyPopulation()
    cached = [person.sessions(ss, np.random.default_rng(k)) for k in range(6)]
    plans = {id(s): logged_plan(s) for s in ss}  # aims afresh at each picked state
    fresh = [reacting_sessions(shipped(), ss, np.random.default_rng(k), plans) for k in range(6)]
    assert sum(len(r) for a in cached for r in a) > 0
    for a, b in zip(cached, fresh, strict=True):
        assert [len(r) for r in a] == [len(r) for r in b]
        for ra, rb in zip(a, b, strict=True):
            for ca, cb in zip(ra, rb, strict=True):
                assert ca["path_sample"] == cb["path_sample"]
                assert np.array_equal(ca["u_h"], cb["u_h"]) and np.array_equal(ca["x"], cb["x"])


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--human", "no-such-person"], "no-such-person"),
        (["--human", "nominal"], "θ̂"),
        (["--human", "fitted-aimed", "--draws", "5"], "--draws"),
        (["--human", "fitted-aimed", "--draws", "100"], "at least 599"),
        (["--human", "fitted-aimed", "--level", "1"], "--level"),
        (["--human", "fitted-aimed", "--human-kwargs", "[1]"], "--human-kwargs"),
        (["--human", "fitted-aimed", "--human-kwargs", '{"nope": 1}'], "nope"),
        (["--person", "math:pi"], "--person"),
    ],
)
def test_bad_input_exits_2_naming_it(logs, tmp_path, capsys, extra, needle):
    argv = ["check-human", str(logs), "--out", str(tmp_path / "x"), *extra]
    argv += [] if "--draws" in extra or "--level" in extra else ["--draws", "40", "--level", "0.2"]
    assert needle in cli_error(argv, capsys)
    assert not (tmp_path / "x").exists()  # refused before anything was written
