"""Statistics for paired benchmark runs: descriptives, repeated-measures ANOVA, post-hoc tests.

Every learner in a run sees the same θ*, start state and noise draws (common random numbers), so
runs are the *subjects* of a within-subject design and learners are the levels of one factor:
- a one-way repeated-measures ANOVA across learners, with the Greenhouse–Geisser correction
  (sphericity rarely holds when one learner's spread differs from the others', as here);
- paired post-hoc tests of the reference learner (StROL) against each baseline: a paired t-test
  and, as a robust companion, the Wilcoxon signed-rank test; p-values Holm-corrected across the
  baselines within one env × condition × metric; effect size Cohen's d_z = mean(d) / sd(d).

Pure numpy / scipy: no pandas, no statsmodels. Lower is better for every metric we report.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from strol_gym.lazy import LazyModule

if TYPE_CHECKING:
    from scipy import stats as sps
else:  # scipy loads on first use: `strol-bench --help` does not need it
    sps = LazyModule("scipy.stats")

ALPHA = 0.05


def describe(values: np.ndarray) -> dict[str, float]:
    """Mean, sample std (ddof = 1), SEM, n, and median with quartiles, of the finite values."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    n = len(v)
    nan = math.nan
    if n == 0:
        return {"mean": nan, "std": nan, "sem": nan, "n": 0, "median": nan, "q1": nan, "q3": nan}
    std = float(v.std(ddof=1)) if n > 1 else nan
    q1, med, q3 = (float(q) for q in np.percentile(v, [25, 50, 75]))
    return {
        "mean": float(v.mean()),
        "std": std,
        "sem": std / math.sqrt(n) if n > 1 else nan,
        "n": n,
        "median": med,
        "q1": q1,
        "q3": q3,
    }


@dataclasses.dataclass(frozen=True)
class AnovaResult:
    """One-way repeated-measures ANOVA. ``*_gg`` are Greenhouse–Geisser corrected, ``*_hf``
    Huynh–Feldt (less conservative when ε is near 1; results written before it read as NaN)."""

    n: int
    k: int
    F: float
    df1: float
    df2: float
    p: float
    eps_gg: float
    df1_gg: float
    df2_gg: float
    p_gg: float
    eps_hf: float = math.nan
    p_hf: float = math.nan

    @classmethod
    def from_row(cls, row: dict[str, Any]) -> AnovaResult:
        """The result from a row of ``anova.csv`` (its fields; other keys are ignored, fields
        added later read as their default)."""
        return cls(**{f.name: row.get(f.name, f.default) for f in dataclasses.fields(cls)})

    @property
    def no_variance(self) -> bool:
        """The data were valid (n, k ≥ 2, finite) but the error variance is zero: F and p are
        NaN rather than F = inf, p = 0, which would read as significant on no evidence."""
        return self.n >= 2 and self.k >= 2 and math.isnan(self.F) and math.isfinite(self.eps_gg)

    def line(self) -> str:
        """APA-style sentence with the corrected degrees of freedom."""
        if self.no_variance:
            return (
                "F and p undefined (no within-subject error variance: every subject's levels "
                f"differ by the same amounts; n = {self.n}, k = {self.k})"
            )
        if not math.isfinite(self.F):
            return f"repeated-measures ANOVA not defined (n = {self.n}, k = {self.k})"
        return (
            f"F({self.df1_gg:.1f}, {self.df2_gg:.1f}) = {self.F:.2f}, "
            f"{format_p(self.p_gg)} (Greenhouse–Geisser ε = {self.eps_gg:.3f}; n = {self.n})"
            + (
                f"; Huynh–Feldt ε = {self.eps_hf:.3f}, {format_p(self.p_hf)}"
                if math.isfinite(self.eps_hf)
                else ""
            )
        )


def greenhouse_geisser_epsilon(y: np.ndarray) -> float:
    """GG ε from the double-centred covariance of the k levels: (tr S̃)² / ((k−1) tr S̃²).

    Lies in [1/(k−1), 1]; 1 means sphericity. NaN when every level difference is constant.
    """
    y = np.asarray(y, dtype=np.float64)
    k = y.shape[1]
    s = np.cov(y, rowvar=False, ddof=1)
    c = np.eye(k) - np.full((k, k), 1.0 / k)
    sc = c @ s @ c
    denom = (k - 1) * float(np.sum(sc * sc))
    if denom <= 0:
        return math.nan
    return float(np.trace(sc) ** 2 / denom)


def huynh_feldt_epsilon(eps_gg: float, n: int, k: int) -> float:
    """Huynh–Feldt ε from GG ε̂ for one group of n subjects and k levels, with Lecoutre's
    (1991) correction: ((n+1)(k−1)ε̂ − 2) / ((k−1)(n−1−(k−1)ε̂)), kept in [ε̂, 1]."""
    if not math.isfinite(eps_gg) or n < 2 or k < 2:
        return math.nan
    denom = (k - 1) * (n - 1 - (k - 1) * eps_gg)
    if denom <= 0:
        return 1.0
    return min(max(((n + 1) * (k - 1) * eps_gg - 2) / denom, eps_gg), 1.0)


def rm_anova(y: np.ndarray) -> AnovaResult:
    """One-way repeated-measures ANOVA on ``y`` of shape (n subjects, k levels), no missing data."""
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 2:
        raise ValueError(f"y must have shape (n subjects, k levels), got {y.shape}")
    n, k = y.shape
    nan = math.nan
    if n < 2 or k < 2 or not np.isfinite(y).all():
        return AnovaResult(n, k, nan, k - 1.0, (k - 1.0) * (n - 1.0), nan, nan, nan, nan, nan)
    grand = y.mean()
    ss_levels = n * float(np.sum((y.mean(axis=0) - grand) ** 2))
    ss_subjects = k * float(np.sum((y.mean(axis=1) - grand) ** 2))
    ss_total = float(np.sum((y - grand) ** 2))
    ss_error = max(ss_total - ss_levels - ss_subjects, 0.0)
    df1, df2 = k - 1.0, (k - 1.0) * (n - 1.0)
    # No error variance (every subject's levels differ by the same amounts, e.g. a constant
    # metric): F = MS_levels / 0 is undefined, not infinite evidence. Report NaN, not F = inf,
    # p = 0.
    if ss_error <= 1e-12 * max(ss_total, 1e-300):
        f = nan
    else:
        f = (ss_levels / df1) / (ss_error / df2)
    p = float(sps.f.sf(f, df1, df2)) if math.isfinite(f) else nan
    eps = greenhouse_geisser_epsilon(y)
    if not math.isfinite(eps):
        eps = 1.0 / df1  # the lower bound: the most conservative correction
    eps = min(max(eps, 1.0 / df1), 1.0)
    p_gg = float(sps.f.sf(f, eps * df1, eps * df2)) if math.isfinite(f) else nan
    hf = huynh_feldt_epsilon(eps, n, k)
    p_hf = float(sps.f.sf(f, hf * df1, hf * df2)) if math.isfinite(f) else nan
    return AnovaResult(n, k, float(f), df1, df2, p, eps, eps * df1, eps * df2, p_gg, hf, p_hf)


def holm(pvalues: Sequence[float]) -> np.ndarray:
    """Holm–Bonferroni step-down adjusted p-values; NaNs stay NaN and do not count in m."""
    p = np.asarray(pvalues, dtype=np.float64)
    out = np.full(p.shape, np.nan)
    ok = np.flatnonzero(np.isfinite(p))
    m = len(ok)
    if m == 0:
        return out
    order = ok[np.argsort(p[ok], kind="stable")]
    adjusted = np.minimum(1.0, (m - np.arange(m)) * p[order])
    out[order] = np.maximum.accumulate(adjusted)
    return out


@dataclasses.dataclass(frozen=True)
class PairedTest:
    """Reference minus baseline on paired samples (negative mean_diff: reference lower)."""

    n: int
    mean_diff: float
    sd_diff: float
    t: float
    df: float
    p_t: float
    ci_low: float
    ci_high: float
    wilcoxon_w: float
    p_wilcoxon: float
    d_z: float
    hl_diff: float
    """Hodges–Lehmann estimate (median of the Walsh averages): the Wilcoxon test's location."""


def paired_test(ref: np.ndarray, base: np.ndarray) -> PairedTest:
    """Paired t-test and Wilcoxon signed-rank test of ``ref − base``, with Cohen's d_z.

    When every difference is zero the learners are indistinguishable on these runs: p = 1.
    When every difference is the same non-zero number, t is infinite and p = 0.
    """
    d = np.asarray(ref, dtype=np.float64) - np.asarray(base, dtype=np.float64)
    d = d[np.isfinite(d)]
    n = len(d)
    nan = math.nan
    if n < 2:
        return PairedTest(n, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan)
    mean, sd = float(d.mean()), float(d.std(ddof=1))
    df = n - 1.0
    if sd == 0.0:
        if mean == 0.0:
            return PairedTest(n, 0.0, 0.0, 0.0, df, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
        inf = math.copysign(math.inf, mean)
        return PairedTest(n, mean, 0.0, inf, df, 0.0, mean, mean, 0.0, nan, inf, mean)
    se = sd / math.sqrt(n)
    t = mean / se
    p_t = float(2.0 * sps.t.sf(abs(t), df))
    half = float(sps.t.ppf(1 - ALPHA / 2, df)) * se
    if np.all(d == 0):
        w, p_w = 0.0, 1.0
    else:
        res = sps.wilcoxon(d, zero_method="wilcox", alternative="two-sided")
        w, p_w = float(res.statistic), float(res.pvalue)
    hl = hodges_lehmann(d)
    return PairedTest(n, mean, sd, t, df, p_t, mean - half, mean + half, w, p_w, mean / sd, hl)


def hodges_lehmann(d: np.ndarray) -> float:
    """Median of the Walsh averages (d_i + d_j)/2, i ≤ j: the one-sample HL location estimate."""
    d = np.asarray(d, dtype=np.float64)
    i, j = np.triu_indices(len(d))
    return float(np.median(0.5 * (d[i] + d[j])))


def format_p(p: float) -> str:
    """'p = 0.012' or 'p < 0.001'."""
    if not math.isfinite(p):
        return "p = n/a"
    if p < 0.001:
        return "p < 0.001"
    return f"p = {p:.3f}"


def plain_language(
    ref_name: str, base_name: str, mean_diff: float, p_holm: float, alpha: float = ALPHA
) -> str:
    """'StROL lower than Gradient, p = …' or 'no significant difference …'."""
    if math.isfinite(p_holm) and p_holm < alpha and math.isfinite(mean_diff) and mean_diff != 0:
        word = "lower" if mean_diff < 0 else "higher"
        return f"{ref_name} {word} than {base_name}, {format_p(p_holm)} (Holm)"
    return (
        f"no significant difference between {ref_name} and {base_name} ({format_p(p_holm)}, Holm)"
    )


def compare_to_reference(
    y: np.ndarray, learners: Sequence[str], reference: str
) -> list[dict[str, Any]]:
    """Post-hoc tests of ``reference`` against every other column of ``y`` (n, k), Holm-corrected.

    Holm runs separately over the t-test p-values and over the Wilcoxon p-values, each across the
    k − 1 baselines (one family per env × condition × metric).
    """
    learners = list(learners)
    if reference not in learners:
        raise ValueError(f"reference learner {reference!r} is not among {learners}")
    r = learners.index(reference)
    tests = [(b, paired_test(y[:, r], y[:, j])) for j, b in enumerate(learners) if j != r]
    p_holm = holm([t.p_t for _, t in tests])
    pw_holm = holm([t.p_wilcoxon for _, t in tests])
    rows: list[dict[str, float | str | int | bool]] = []
    for (base, t), ph, pwh in zip(tests, p_holm, pw_holm, strict=True):
        rows.append(
            {
                "learner": reference,
                "baseline": base,
                "test": "paired t",
                "n": t.n,
                "mean_diff": t.mean_diff,
                "ci95_low": t.ci_low,
                "ci95_high": t.ci_high,
                "statistic": t.t,
                "df": t.df,
                "p_raw": t.p_t,
                "p_holm": float(ph),
                "effect_size": t.d_z,
                "effect_size_name": "cohen_dz",
                "wilcoxon_W": t.wilcoxon_w,
                "wilcoxon_p_raw": t.p_wilcoxon,
                "wilcoxon_p_holm": float(pwh),
                "hodges_lehmann": t.hl_diff,
                "significant": bool(math.isfinite(ph) and ph < ALPHA),
            }
        )
    return rows


def direction(row: dict, test: str = "t", alpha: float = ALPHA) -> int:
    """−1 if the reference is significantly lower than the baseline, +1 if higher, 0 if neither.

    ``test="t"``: Holm-corrected paired t and the mean difference; ``"wilcoxon"``:
    Holm-corrected signed-rank test and the Hodges–Lehmann estimate.
    """
    p, est = (
        (row["p_holm"], row["mean_diff"])
        if test == "t"
        else (row["wilcoxon_p_holm"], row["hodges_lehmann"])
    )
    if not (math.isfinite(p) and p < alpha and math.isfinite(est)) or est == 0:
        return 0
    return -1 if est < 0 else 1


def stars(p: float) -> str:
    """'***' p < 0.001, '**' p < 0.01, '*' p < 0.05, '' otherwise."""
    if not math.isfinite(p):
        return ""
    return "***" if p < 0.001 else "**" if p < 0.01 else "*" if p < 0.05 else ""


LOWER, HIGHER = "↓", "↑"
"""The direction of a significant difference, always read as the reference learner (StROL)
against the learner whose cell carries the mark: ↓ reference lower, ↑ reference higher."""
MARK_LEGEND = (
    f"{LOWER} = {{ref}} significantly lower than that learner, {HIGHER} = {{ref}} significantly "
    "higher ({test}, Holm across the baselines; * p < 0.05, ** p < 0.01, *** p < 0.001); "
    "no mark: not significant"
)
"""The one convention every table and figure states (``mark_legend``)."""
TEST_NAMES = {"t": "paired t", "wilcoxon": "Wilcoxon signed-rank"}


def mark(row: dict | None, test: str = "t", alpha: float = ALPHA) -> str:
    """'↓***' / '↑*' for a post-hoc row (``compare_to_reference``) whose test is significant:
    the arrow is the reference's direction against that baseline, the stars its Holm p; ''
    otherwise (and for no row)."""
    if not row:
        return ""
    if test == "t":
        return signed_stars(row["mean_diff"], row["p_holm"], alpha)
    return signed_stars(row["hodges_lehmann"], row["wilcoxon_p_holm"], alpha)


def signed_stars(estimate: float, p: float, alpha: float = ALPHA) -> str:
    """'↓**' when ``p`` < ``alpha`` and the estimated difference (first minus second) is
    negative, '↑**' when positive, '' when not significant or no direction."""
    if not (math.isfinite(p) and p < alpha and math.isfinite(estimate)) or estimate == 0:
        return ""
    return (LOWER if estimate < 0 else HIGHER) + stars(p)


def mark_legend(reference: str, test: str = "t") -> str:
    """The marks' legend with the reference learner's name and the test behind the marks."""
    return MARK_LEGEND.format(ref=reference, test=TEST_NAMES[test])
