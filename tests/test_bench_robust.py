"""The heavy-tail statistics (IQM, probability of improvement, performance profiles, stratified
bootstrap) against hand-worked cases, known properties and coverage on simulated data."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps
from strol_gym.benchmarks.analysis import robust, stats

RESAMPLES = 200


def test_iqm_hand_cases():
    # n = 8: cut 2 from each end -> mean(3, 4, 5, 6) = 4.5, whatever the tails are.
    assert robust.iqm(np.array([-1e9, 2, 3, 4, 5, 6, 7, 1e9])) == pytest.approx(4.5)
    # n = 5: ⌊5/4⌋ = 1 cut from each end -> mean(2, 3, 4).
    assert robust.iqm(np.array([100.0, 1, 4, 2, 3])) == pytest.approx(3.0)
    # n = 3: nothing is cut -> the mean.
    assert robust.iqm(np.array([0.0, 1.0, 5.0])) == pytest.approx(2.0)
    # Column-wise on a matrix.
    y = np.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0], [4.0, 40.0]])
    assert np.allclose(robust.iqm(y, axis=0), [2.5, 25.0])


def test_iqm_of_a_symmetric_sample_is_its_centre():
    x = 3.0 + np.array([-5.0, -2.0, -1.0, -0.5, 0.5, 1.0, 2.0, 5.0])
    assert robust.iqm(x) == pytest.approx(3.0)
    assert robust.iqm(x) == pytest.approx(np.median(x))


def test_iqm_ignores_a_heavy_tail_that_moves_the_mean():
    x = np.zeros(100)
    x[:8] = 5.0  # regret-like: 8 runs beyond a regime switch
    assert robust.iqm(x) == 0.0
    assert x.mean() == pytest.approx(0.4)


def test_poi_hand_case_and_ties():
    ref = np.array([0.0, 1.0, 2.0, 3.0])
    base = np.array([1.0, 1.0, 1.0, 5.0])
    # runs: win, tie, loss, win -> (1 + 0.5 + 0 + 1) / 4
    assert robust.probability_of_improvement(ref, base) == pytest.approx(0.625)
    # higher is better flips the wins and losses, the tie stays ½
    assert robust.probability_of_improvement(ref, base, lower_is_better=False) == 0.375
    # a tolerance turns near-ties into ties
    assert robust.probability_of_improvement(
        np.array([1.0, 2.0]), np.array([1.0 + 1e-9, 3.0]), tol=1e-6
    ) == pytest.approx(0.75)


def test_poi_of_identical_samples_is_one_half_with_a_degenerate_interval():
    x = np.random.default_rng(1).normal(size=30)
    assert robust.probability_of_improvement(x, x) == 0.5
    res = robust.poi_interval(
        np.column_stack([x, x]), 0, rng=robust.cell_rng("t"), resamples=RESAMPLES
    )
    assert np.array_equal(res.estimate, [0.5, 0.5])
    assert np.array_equal(res.low, [0.5, 0.5]) and np.array_equal(res.high, [0.5, 0.5])


def test_poi_is_antisymmetric():
    rng = np.random.default_rng(2)
    a, b = rng.exponential(size=40), rng.exponential(size=40)
    b[:5] = a[:5]  # some ties
    p_ab = robust.probability_of_improvement(a, b)
    p_ba = robust.probability_of_improvement(b, a)
    assert p_ab + p_ba == pytest.approx(1.0)


def test_intervals_are_seeded_and_contain_the_estimate():
    y = np.random.default_rng(3).exponential(size=(60, 3))
    one = robust.iqm_interval(y, rng=robust.cell_rng("robot", "training"), resamples=RESAMPLES)
    two = robust.iqm_interval(y, rng=robust.cell_rng("robot", "training"), resamples=RESAMPLES)
    other = robust.iqm_interval(y, rng=robust.cell_rng("robot", "clean"), resamples=RESAMPLES)
    assert all(np.array_equal(getattr(one, f), getattr(two, f)) for f in ("low", "high"))
    assert not np.array_equal(one.low, other.low)
    assert np.all(one.low <= one.estimate) and np.all(one.estimate <= one.high)
    poi = robust.poi_interval(y, 2, rng=robust.cell_rng("x"), resamples=RESAMPLES)
    assert np.all(poi.low <= poi.estimate) and np.all(poi.estimate <= poi.high)
    assert poi.estimate[2] == 0.5


def test_stratified_resamples_stay_within_their_stratum():
    strata = np.array(["a"] * 3 + ["b"] * 5 + ["a"] * 2)
    idx = robust.bootstrap_indices(10, 50, np.random.default_rng(0), strata)
    assert idx.shape == (50, 10)
    assert np.all(strata[idx] == strata[None, :])
    # every row of stratum b is drawn from b's rows only, and all of them appear somewhere
    assert set(np.unique(idx[:, strata == "b"])) == set(np.flatnonzero(strata == "b"))


def test_stratified_interval_of_a_constant_stratum_shift():
    # Two strata whose values do not vary within the stratum: every stratified resample keeps
    # the strata's sizes, so the IQM never moves; an unstratified bootstrap does move it.
    y = np.array([0.0] * 6 + [10.0] * 6)
    strata = [0] * 6 + [1] * 6
    res = robust.iqm_interval(y, rng=np.random.default_rng(0), resamples=100, strata=strata)
    assert res.low[0] == res.high[0] == pytest.approx(5.0)
    free = robust.iqm_interval(y, rng=np.random.default_rng(0), resamples=100)
    assert free.high[0] - free.low[0] > 1.0


def test_iqm_interval_covers_the_truth_on_simulated_data():
    # Normal data: the population IQM of a symmetric distribution is its centre. 40 samples of
    # 60 runs each, 200 resamples: a 95 % interval should miss a handful of times at most.
    rng = np.random.default_rng(4)
    hits = 0
    for k in range(40):
        y = rng.normal(1.0, 2.0, size=60)
        res = robust.iqm_interval(y, rng=np.random.default_rng(k), resamples=RESAMPLES)
        hits += bool(res.low[0] <= 1.0 <= res.high[0])
    assert hits >= 34


def test_poi_interval_covers_the_truth_on_simulated_data():
    # d = ref − base ~ N(−0.3, 1) per run: P(ref lower) = Φ(0.3).
    truth = float(sps.norm.cdf(0.3))
    rng = np.random.default_rng(5)
    hits = 0
    for k in range(40):
        base = rng.exponential(size=80)
        ref = base + rng.normal(-0.3, 1.0, size=80)
        y = np.column_stack([ref, base])
        res = robust.poi_interval(y, 0, rng=np.random.default_rng(k), resamples=RESAMPLES)
        hits += bool(res.low[1] <= truth <= res.high[1])
    assert hits >= 34


def test_performance_profile_hand_case():
    scores = np.array([[0.0, 1.0], [0.5, 1.0], [2.0, np.nan], [3.0, 0.0]])
    prof = robust.performance_profile(scores, np.array([-1.0, 0.0, 0.5, 1.0, 3.0]))
    assert np.allclose(prof[0], [0, 0.25, 0.5, 0.5, 1.0])
    assert np.allclose(prof[1], [0, 1 / 3, 1 / 3, 1.0, 1.0])  # the NaN run is left out


def test_profile_taus_span_the_scores():
    s = np.array([0.0, 1e-4, 0.01, 3.0])
    lin = robust.profile_taus(s, 11)
    assert lin[0] == 0.0 and lin[-1] == 3.0 and len(lin) == 11
    log = robust.profile_taus(s, 11, log=True)
    assert log[0] == 0.0 and log[1] == pytest.approx(1e-4) and log[-1] == pytest.approx(3.0)
    assert np.all(np.diff(log) > 0)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: robust.iqm(np.array([])), "at least one"),
        (lambda: robust.bootstrap_indices(0, 10, np.random.default_rng()), "n must"),
        (lambda: robust.bootstrap_indices(3, 0, np.random.default_rng()), "resamples"),
        (lambda: robust.bootstrap_indices(3, 5, np.random.default_rng(), [0, 1]), "strata"),
        (lambda: robust.improvement(np.zeros(2), np.zeros(2), tol=-1), "tol"),
        (lambda: robust.probability_of_improvement(np.zeros(0), np.zeros(0)), "at least one"),
        (
            lambda: robust.poi_interval(np.zeros((3, 2)), 2, rng=np.random.default_rng()),
            "reference",
        ),
        (
            lambda: robust.iqm_interval(np.array([[np.nan]]), rng=np.random.default_rng()),
            "finite",
        ),
        (
            lambda: robust.iqm_interval(np.ones((3, 1)), rng=np.random.default_rng(), level=1.0),
            "level",
        ),
        (lambda: robust.profile_taus(np.array([np.nan])), "finite"),
    ],
)
def test_bad_input_names_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_marks_carry_the_reference_direction():
    row = {"p_holm": 0.0004, "mean_diff": -0.2, "wilcoxon_p_holm": 0.03, "hodges_lehmann": 0.1}
    assert stats.mark(row) == "↓***"
    assert stats.mark(row, "wilcoxon") == "↑*"
    assert stats.mark({**row, "p_holm": 0.2}) == ""
    assert stats.mark(None) == ""
    assert "↓ = StROL significantly lower" in stats.mark_legend("StROL")


def test_resamples_come_from_the_environment_when_set(monkeypatch):
    monkeypatch.delenv(robust.RESAMPLES_VAR, raising=False)
    assert robust.default_resamples() == robust.BOOTSTRAP_RESAMPLES == 2000
    monkeypatch.setenv(robust.RESAMPLES_VAR, "150")
    assert robust.default_resamples() == 150
    for bad in ("0", "-3", "2.5", "many", "2000000"):
        monkeypatch.setenv(robust.RESAMPLES_VAR, bad)
        with pytest.raises(ValueError, match=robust.RESAMPLES_VAR):
            robust.default_resamples()


def test_chunked_resamples_give_the_bytes_of_one_block(monkeypatch):
    y = np.random.default_rng(6).exponential(size=(50, 3))
    whole = robust.iqm_interval(y, rng=np.random.default_rng(1), resamples=RESAMPLES)
    monkeypatch.setattr(robust, "CHUNK_VALUES", 7 * 50 * 3)  # 7 resamples per block
    chunked = robust.iqm_interval(y, rng=np.random.default_rng(1), resamples=RESAMPLES)
    assert np.array_equal(whole.low, chunked.low) and np.array_equal(whole.high, chunked.high)
