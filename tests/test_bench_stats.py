"""The benchmark statistics against a small case worked out by hand."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats as sps

from strol_gym.benchmarks.analysis import stats

# 4 subjects (runs) × 3 levels (learners).
Y = np.array(
    [
        [1.0, 2.0, 4.0],
        [2.0, 3.0, 3.0],
        [3.0, 5.0, 7.0],
        [2.0, 2.0, 4.0],
    ]
)


def test_describe_hand_case():
    # column 3: 4, 3, 7, 4 -> mean 4.5, deviations -.5 -1.5 2.5 -.5 -> SS 9, var 3.
    d = stats.describe(Y[:, 2])
    assert d["n"] == 4
    assert d["mean"] == pytest.approx(4.5)
    assert d["std"] == pytest.approx(math.sqrt(3.0))
    assert d["sem"] == pytest.approx(math.sqrt(3.0) / 2.0)


def test_rm_anova_hand_case():
    # Level means 2, 3, 4.5; grand mean 19/6.
    # SS_levels = 4 * ((7/6)^2 + (1/6)^2 + (8/6)^2) = 456/36
    # SS_subjects = 3 * ((5/6)^2 + (3/6)^2 + (11/6)^2 + (3/6)^2) = 492/36
    # SS_total = 150 - 12 * (19/6)^2 = 89/3;  SS_error = 89/3 - 948/36 = 10/3
    # F = (456/36 / 2) / (10/3 / 6) = 11.4 with df (2, 6).
    # For F(2, ν): P(F > f) = (1 + 2f/ν)^(-ν/2) = 4.8^-3.
    res = stats.rm_anova(Y)
    assert (res.n, res.k, res.df1, res.df2) == (4, 3, 2.0, 6.0)
    assert res.F == pytest.approx(11.4)
    assert res.p == pytest.approx(4.8**-3)
    # Covariance of the levels S = [[2/3,1,1],[1,2,2],[1,2,3]]; double-centred it is
    # [[11,-1,-10],[-1,5,-4],[-10,-4,14]] / 27: trace 30/27, sum of squares 576/729,
    # ε = (30/27)^2 / (2 * 576/729) = 900/1152.
    assert res.eps_gg == pytest.approx(900 / 1152)
    assert res.df1_gg == pytest.approx(2 * 900 / 1152)
    assert res.df2_gg == pytest.approx(6 * 900 / 1152)
    assert res.p_gg == pytest.approx(sps.f.sf(11.4, 2 * 900 / 1152, 6 * 900 / 1152))
    assert res.p < res.p_gg < 0.05
    assert "F(1.6, 4.7) = 11.40" in res.line()
    # Huynh–Feldt (Lecoutre): (5 * 2 * 900/1152 - 2) / (2 * (3 - 2 * 900/1152)) = 2.02 > 1
    assert res.eps_hf == 1.0 and res.p_hf == pytest.approx(res.p)


def test_huynh_feldt_lies_between_greenhouse_geisser_and_one():
    rng = np.random.default_rng(0)
    for n, k in [(6, 3), (12, 5), (40, 4)]:
        y = rng.normal(size=(n, k)) * np.linspace(0.2, 3.0, k) + np.arange(k)  # ε < 1, F > 1
        res = stats.rm_anova(y)
        assert res.eps_gg <= res.eps_hf <= 1.0
        assert res.p_gg >= res.p_hf >= res.p
        e, m = res.eps_gg, k - 1
        want = min(max(((n + 1) * m * e - 2) / (m * (n - 1 - m * e)), e), 1.0)
        assert res.eps_hf == pytest.approx(want)
    old = ("n", "k", "F", "df1", "df2", "p", "eps_gg", "df1_gg", "df2_gg", "p_gg")
    read = stats.AnovaResult.from_row(dict.fromkeys(old, 1.0))  # a row written before HF
    assert math.isnan(read.eps_hf) and "Huynh" not in read.line()


def test_rm_anova_two_levels_is_paired_t_squared():
    t = stats.paired_test(Y[:, 0], Y[:, 2])
    res = stats.rm_anova(Y[:, [0, 2]])
    assert res.F == pytest.approx(t.t**2)
    assert res.p == pytest.approx(t.p_t)
    assert res.eps_gg == pytest.approx(1.0)


def test_paired_test_hand_case():
    # d = col1 - col2 = (-1, -1, -2, 0): mean -1, sd sqrt(2/3), t = -1 / (sd / 2) = -sqrt(6).
    t = stats.paired_test(Y[:, 0], Y[:, 1])
    assert t.n == 4 and t.df == 3
    assert t.mean_diff == pytest.approx(-1.0)
    assert t.t == pytest.approx(-math.sqrt(6.0))
    assert t.d_z == pytest.approx(-math.sqrt(1.5))
    assert t.p_t == pytest.approx(2 * sps.t.sf(math.sqrt(6.0), 3))
    half = sps.t.ppf(0.975, 3) * math.sqrt(2 / 3) / 2
    assert (t.ci_low, t.ci_high) == pytest.approx((-1 - half, -1 + half))
    # Wilcoxon drops the zero; |d| ranks 1.5, 1.5, 3, all negative: W+ = 0 = min(W+, W-).
    assert t.wilcoxon_w == 0.0
    assert 0 < t.p_wilcoxon <= 1


def test_paired_test_degenerate_cases():
    same = stats.paired_test(Y[:, 0], Y[:, 0])
    assert same.p_t == 1.0 and same.mean_diff == 0.0 and same.p_wilcoxon == 1.0
    shifted = stats.paired_test(Y[:, 0] - 1.0, Y[:, 0])
    assert shifted.p_t == 0.0 and shifted.t == -math.inf


def test_holm_hand_case():
    # sorted 0.01, 0.03, 0.04 -> 3*0.01, 2*0.03, 1*0.04 -> cumulative max 0.03, 0.06, 0.06.
    np.testing.assert_allclose(stats.holm([0.01, 0.04, 0.03]), [0.03, 0.06, 0.06])
    np.testing.assert_allclose(stats.holm([0.5, 0.9]), [1.0, 1.0])
    out = stats.holm([0.02, math.nan])
    assert out[0] == pytest.approx(0.02) and math.isnan(out[1])


def test_compare_to_reference_and_language():
    rows = stats.compare_to_reference(Y, ["strol", "gradient", "one"], "strol")
    assert [r["baseline"] for r in rows] == ["gradient", "one"]
    p = [r["p_raw"] for r in rows]
    np.testing.assert_allclose([r["p_holm"] for r in rows], stats.holm(p))
    assert all(r["mean_diff"] < 0 for r in rows)
    line = stats.plain_language("StROL", "One", rows[1]["mean_diff"], 0.01)
    assert line == "StROL lower than One, p = 0.010 (Holm)"
    assert stats.plain_language("StROL", "One", 0.2, 0.3).startswith("no significant difference")
    assert stats.stars(0.0004) == "***" and stats.stars(0.2) == ""
    with pytest.raises(ValueError, match="reference"):
        stats.compare_to_reference(Y, ["a", "b", "c"], "strol")


@pytest.mark.parametrize(
    "y",
    [
        np.array([[1.0, 2.0, 4.0], [3.0, 4.0, 6.0]]),  # level effect, zero error variance
        np.array([[1.0, 2.0], [1.0, 2.0], [1.0, 2.0]]),  # identical subjects
        np.full((2, 4), 0.5),  # a constant metric
    ],
)
def test_rm_anova_without_error_variance_is_undefined_not_significant(y):
    res = stats.rm_anova(y)
    for v in (res.F, res.p, res.p_gg):
        assert math.isnan(v)
    assert res.no_variance
    assert "inf" not in res.line() and "p <" not in res.line()
    assert "undefined (no within-subject error variance" in res.line()
    from strol_gym.benchmarks.analysis.report import ANOVA_COLUMNS
    from strol_gym.benchmarks.experiments.study import _anova_text

    row = {"env": "x", "condition": "c", "metric": "m"} | dataclasses.asdict(res)
    assert stats.AnovaResult.from_row(row) == res
    assert _anova_text(row) == res.line()
    assert set(ANOVA_COLUMNS[3:]) <= set(row)
    assert not stats.rm_anova(Y).no_variance
    assert not stats.rm_anova(np.array([[1.0, 2.0]])).no_variance  # n < 2: another reason
