"""The study's metrics the authors' way, on hand-made traces and trajectories whose numbers are
derived by hand in the comments; and the paper's pooled analysis on hand-made records."""

from __future__ import annotations

import math

import numpy as np
import pytest

from strol_gym.benchmarks.analysis.report import pooled_matrix, pooled_tests
from strol_gym.envs.study import metrics as sa


def _record(times, mags):
    """A correction record whose force has magnitude ``mags`` (a 3-4-5 direction)."""
    mags = np.asarray(mags, dtype=np.float64)
    force = np.stack([0.6 * mags, 0.8 * mags, np.zeros_like(mags)], axis=1)
    return {"times": np.asarray(times, dtype=np.float64), "force": force}


def test_resample_hold_reads_the_latest_sample_at_each_20hz_tick():
    t = 1.0 + 0.025 * np.arange(9)  # 40 Hz
    v = np.arange(9.0)
    # ticks 1.0, 1.05, 1.1, 1.15, 1.2 fall on samples 0, 2, 4, 6, 8
    np.testing.assert_array_equal(sa.resample_hold(t, v), [0.0, 2.0, 4.0, 6.0, 8.0])
    # 30 Hz: ticks 0, .05, .1 -> latest at or before: t=0 (0), t=1/30 (1), t=.1 (3)
    t30 = np.arange(4) / 30.0
    np.testing.assert_array_equal(sa.resample_hold(t30, np.arange(4.0)), [0.0, 1.0, 3.0])


def test_record_samples_counts_new_running_maxima():
    # 16 (new max), 20 (new), 18, 25 (new), 25 (equal: not above), 24, 35 (new) -> 4
    assert sa.record_samples([16, 20, 18, 25, 25, 24, 35]) == 4
    assert sa.record_samples([]) == 0
    assert sa.record_samples([30, 20, 10]) == 1
    assert sa.new_maxima([16, 20, 18, 25, 25, 24, 35]) == [0, 1, 3, 6]


def test_correction_time_resamples_then_counts_then_times_005():
    # 40 Hz trace of ‖F‖: 16, 30, 20, 18, 25, 17, 25, 40, 35 at t = 0, .025, …, .2.
    # Resampled at 20 Hz (t = 0, .05, .1, .15, .2): 16, 20, 25, 25, 35. Running maxima:
    # 16 ✓, 20 ✓, 25 ✓, 25 ✗, 35 ✓ -> 4 samples -> 0.2 s. The 30 and 40 fall between ticks.
    rec = _record(0.025 * np.arange(9), [16, 30, 20, 18, 25, 17, 25, 40, 35])
    assert sa.correction_samples(rec) == 4
    assert sa.correction_time(rec) == pytest.approx(0.2)
    # the env's own 0.05 s steps: resampling changes nothing; 20, 22, 21, 23 -> 3 samples
    rec = _record(0.05 * np.arange(1, 5), [20, 22, 21, 23])
    assert sa.correction_time(rec) == pytest.approx(0.15)


def test_resample_rejects_bad_input():
    with pytest.raises(ValueError, match="dt must be"):
        sa.resample_hold([0.0, 0.1], [1.0, 2.0], dt=0.0)
    with pytest.raises(ValueError, match="times must be 1-D"):
        sa.resample_hold([0.0, 0.1], [1.0])
    with pytest.raises(ValueError, match="non-decreasing"):
        sa.resample_hold([0.1, 0.0], [1.0, 2.0])


class _HandTask:
    """φ(x) = x (4 features); the plan for θ* and for any other θ are fixed by hand."""

    def __init__(self, theta_star, plan_star, plan_other):
        self.theta_star = np.asarray(theta_star, dtype=np.float64)
        self.plans = np.asarray(plan_star, dtype=np.float64), np.asarray(plan_other, float)

    def features(self, x):
        return np.asarray(x, dtype=np.float64)

    def plan(self, theta, x0):
        return np.stack([self.plans[0 if np.array_equal(t, self.theta_star) else 1] for t in theta])


def test_authors_regret_on_a_hand_made_trajectory():
    star = [1.0, 2.0, 3.0, 4.0]
    xi_star = [[0, 0, 0, 0], [1, 1, 1, 1], [2, 2, 0.5, 0.5]]
    xi_hat = [[0, 0, 0, 0], [0, 0, 3, 3], [0, 0, 1, 0]]
    task = _HandTask(star, xi_star, xi_hat)
    # R'(ξ*): features 1-2 over waypoints 1..2: (1·1 + 2·1) + (1·2 + 2·2) = 9; features 3-4 at
    # the last waypoint only: 3·0.5 + 4·0.5 = 3.5 -> 12.5. R'(ξ_θ̂): 0 + 0 and 3·1 + 4·0 = 3.
    # Regret = 12.5 − 3 + 1.1 = 10.6. (Eq. S1 over every waypoint and feature would give
    # (10 + 9.5) − (21 + 3) = −4.5: a different quantity.)
    r = sa.regret(task, [[0.5, 0.5, 0.5, 0.5]], [star], [[0.0, 0.0, 0.0, 0.0]])
    assert r.shape == (1,) and r[0] == pytest.approx(10.6)
    # the learned θ̂ = θ*: the same plan, regret = the constant alone
    assert sa.regret(task, [star], [star], [[0.0] * 4])[0] == pytest.approx(1.1)


def test_authors_return_with_three_features_takes_the_third_at_the_end():
    class Three(_HandTask):
        pass

    plans = np.array([[[0, 0, 0], [1, 2, 4], [3, 1, 2]]], dtype=np.float64)
    # θ* = (1, 1, 10): path 1·1 + 1·2 + 1·3 + 1·1 = 7; table at the end: 10·2 = 20 -> 27
    got = sa.authors_return(Three([0, 0, 0], plans[0], plans[0]), plans, np.array([[1, 1, 10.0]]))
    assert got[0] == pytest.approx(27.0)


def _rec(env, seed, learner, value, cond="c"):
    return {"env": env, "condition": cond, "seed": seed, "learner": learner, "m": value}


def test_pooled_matrix_averages_each_subject_over_the_tasks():
    recs = [
        _rec(env, s, learner, v)
        for env, off in (("t1", 0.0), ("t2", 2.0))
        for s in (1, 2, 3)
        for learner, v in (("a", s + off), ("b", 10.0 * s + off))
    ]
    recs.append(_rec("t3", 1, "a", 100.0))  # another Task, not pooled
    seeds, y = pooled_matrix(recs, ["t1", "t2"], ["a", "b"], "m")
    # seed s: a = mean(s, s + 2) = s + 1; b = mean(10 s, 10 s + 2) = 10 s + 1
    assert seeds == [1, 2, 3]
    np.testing.assert_allclose(y, [[2, 11], [3, 21], [4, 31]])
    recs.append(_rec("t2", 4, "a", 1.0))  # seed 4 lacks b: left out (listwise)
    recs += [_rec("t1", 5, learner, 1.0) for learner in "ab"]  # seed 5 lacks Task t2: left out
    recs[0 * 6 + 1 * 2] = _rec("t1", 2, "a", math.nan)  # a NaN value drops seed 2
    seeds, _ = pooled_matrix(recs, ["t1", "t2"], ["a", "b"], "m")
    assert seeds == [1, 3]


def test_pooled_tests_runs_the_anova_and_every_pair_with_holm():
    rng = np.random.default_rng(0)
    base = rng.normal(size=8)
    recs = [
        _rec(env, s, learner, base[s] + shift + 0.1 * rng.normal())
        for env in ("t1", "t2", "t3")
        for s in range(8)
        for learner, shift in (("one", 1.0), ("mof", 0.9), ("strol", 0.0))
    ]
    out = pooled_tests(recs, ["t1", "t2", "t3"], ["one", "mof", "strol"], "m")
    assert out["n"] == 8 and out["anova"].k == 3 and out["anova"].df2 == 14
    assert out["anova"].p_gg < 0.001  # StROL sits a whole unit lower, noise 0.1
    assert [(p["a"], p["b"]) for p in out["pairs"]] == [
        ("one", "mof"),
        ("one", "strol"),
        ("mof", "strol"),
    ]
    for p in out["pairs"]:
        assert p["p_holm"] >= p["p_t"]
    assert out["pairs"][1]["mean_diff"] > 0.8 and out["pairs"][1]["p_holm"] < 0.001
