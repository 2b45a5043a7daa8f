"""From per-run records to summary.csv, stats.csv, anova.csv, summary.md and the H1/H2 verdicts.

The analysis is a pure function of the records and the config, so ``strol-bench report`` can
re-render a folder at any time and always produce the same tables.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.analysis import robust, stats
from strol_gym.benchmarks.analysis.base import (
    METRIC_LABELS,
    METRICS,
    Analysis,
    _f,
    _matrix,
    display,
)
from strol_gym.benchmarks.engine.conditions import PAPER_LEARNERS, REFERENCE_LEARNER, env_preset
from strol_gym.benchmarks.engine.config import BenchConfig
from strol_gym.benchmarks.engine.record import RunRecord, value
from strol_gym.benchmarks.engine.results import ResultsDir, write_csv
from strol_gym.files import write_text_atomic
from strol_gym.metrics import METRICS as METRIC_TABLE

CELL_KEYS = ("mean", "std", "sem", "median", "n")
"""The descriptives an experiment's own table copies from a summary cell."""
IQM_KEYS = ("iqm", "iqm_ci95_low", "iqm_ci95_high")
"""A learner's IQM and its 95 % bootstrap interval (summary.csv's columns)."""
POI_KEYS = ("prob_improvement", "prob_improvement_ci95_low", "prob_improvement_ci95_high")
"""P(reference better in a run) and its 95 % bootstrap interval (stats.csv's columns)."""
SUMMARY_COLUMNS = (
    "env",
    "condition",
    "learner",
    "metric",
    "mean",
    "std",
    "sem",
    "n",
    "median",
    "q1",
    "q3",
    *IQM_KEYS,
)
STATS_COLUMNS = (
    "env",
    "condition",
    "metric",
    "learner",
    "baseline",
    "test",
    "n",
    "mean_diff",
    "ci95_low",
    "ci95_high",
    "statistic",
    "df",
    "p_raw",
    "p_holm",
    "effect_size",
    "effect_size_name",
    "wilcoxon_W",
    "wilcoxon_p_raw",
    "wilcoxon_p_holm",
    "hodges_lehmann",
    "significant",
    "plain_language",
    *POI_KEYS,
    "mark",
)
ANOVA_COLUMNS = (
    "env",
    "condition",
    "metric",
    "n",
    "k",
    "F",
    "df1",
    "df2",
    "p",
    "eps_gg",
    "df1_gg",
    "df2_gg",
    "p_gg",
    "eps_hf",
    "p_hf",
)


def pooled_matrix(
    records: Sequence[RunRecord], envs: Sequence[str], learners: Sequence[str], key: str
) -> tuple[list[int], np.ndarray]:
    """(seeds, learners): each run seed's mean of ``key`` over every (env, condition) cell of
    ``envs`` it ran in, as the paper pools a participant over its Tasks (or a simulated human
    over the conditions). Listwise: a seed enters only with a finite value for every learner
    in every cell, and only if it ran in as many cells as any seed did."""
    cells: dict[tuple[int, str, str], dict[str, float]] = {}
    for r in records:
        if r["env"] in envs and r["learner"] in learners:
            cells.setdefault((r["seed"], r["env"], r["condition"]), {})[r["learner"]] = _f(
                value(r, key)
            )
    per_seed: dict[int, list[list[float]]] = {}
    bad: set[int] = set()
    for (seed, _, _), vals in cells.items():
        row = [vals.get(learner, math.nan) for learner in learners]
        if not np.isfinite(row).all():
            bad.add(seed)
        per_seed.setdefault(seed, []).append(row)
    full = max((len(v) for v in per_seed.values()), default=0)
    seeds = sorted(s for s, v in per_seed.items() if s not in bad and len(v) == full)
    y = np.array([np.mean(per_seed[s], axis=0) for s in seeds], dtype=np.float64)
    return seeds, y.reshape(len(seeds), len(learners))


def pooled_tests(
    records: Sequence[RunRecord], envs: Sequence[str], learners: Sequence[str], key: str
) -> dict[str, Any]:
    """The paper's pooled analysis: ``pooled_matrix``, a repeated-measures ANOVA over the
    learners (Greenhouse–Geisser), then every pair of learners (paired t and Wilcoxon, each
    Holm-corrected over the pairs). Pair rows: first minus second."""
    seeds, y = pooled_matrix(records, envs, learners, key)
    pairs = [(i, j) for i in range(len(learners)) for j in range(i + 1, len(learners))]
    tests = [stats.paired_test(y[:, i], y[:, j]) for i, j in pairs]
    p_holm = stats.holm([t.p_t for t in tests])
    pw_holm = stats.holm([t.p_wilcoxon for t in tests])
    rows = [
        {
            "a": learners[i],
            "b": learners[j],
            "n": t.n,
            "mean_diff": t.mean_diff,
            "t": t.t,
            "p_t": t.p_t,
            "p_holm": float(ph),
            "p_wilcoxon": t.p_wilcoxon,
            "wilcoxon_p_holm": float(pwh),
        }
        for (i, j), t, ph, pwh in zip(pairs, tests, p_holm, pw_holm, strict=True)
    ]
    means = dict(zip(learners, y.mean(axis=0).tolist() if len(seeds) else [], strict=False))
    return {
        "envs": list(envs),
        "learners": list(learners),
        "metric": key,
        "n": len(seeds),
        "means": means,
        "anova": stats.rm_anova(y),
        "pairs": rows,
    }


def pooled_lines(result: dict[str, Any]) -> list[str]:
    """Markdown bullets: the ANOVA, then each pair (Holm)."""
    an = result["anova"]
    names = ", ".join(map(display, result["learners"]))
    out = [
        f"- repeated-measures ANOVA over {names}: {an.line()}; uncorrected "
        f"F({an.df1:g}, {an.df2:g}), {stats.format_p(an.p)}"
    ]
    for r in result["pairs"]:
        out.append(
            f"  - {display(r['a'])} − {display(r['b'])}: Δ = {fmt(r['mean_diff'])}, paired t "
            f"{stats.format_p(r['p_holm'])} (Holm; raw {stats.format_p(r['p_t'])}), Wilcoxon "
            f"{stats.format_p(r['wilcoxon_p_holm'])} (Holm)"
        )
    return out


def lower_is_better(metric: str) -> bool:
    """The metric's direction (metrics a user's env reports unregistered: lower is better)."""
    m = METRIC_TABLE.get(metric)
    return True if m is None else m.lower_is_better


def robust_cell(
    y: np.ndarray,
    learners: Sequence[str],
    reference: str,
    key: Sequence[str],
    resamples: int,
    strata: Sequence[object] | None = None,
) -> tuple[robust.Interval, robust.Interval | None]:
    """IQM of every learner and P(reference better in a run) against each, with stratified
    bootstrap intervals over the paired runs of ``y`` (runs × learners), seeded by ``key``."""
    rng = robust.cell_rng(*key)
    iqm = robust.iqm_interval(y, rng=rng, resamples=resamples, strata=strata)
    if reference not in learners or len(learners) < 2:
        return iqm, None
    poi = robust.poi_interval(
        y,
        list(learners).index(reference),
        rng=rng,
        resamples=resamples,
        strata=strata,
        lower_is_better=lower_is_better(key[-1]),
    )
    return iqm, poi


def aggregate(
    a: Analysis, cells: Sequence[tuple[str, str]], metric: str, resamples: int
) -> dict[str, Any] | None:
    """IQM and P(improvement) over every run of the (env, condition) ``cells``, bootstrapped
    within each cell (stratified, rliable's aggregate over tasks); None with fewer than two."""
    ys = [(k, a.runs[(*k, metric)]) for k in cells if (*k, metric) in a.runs]
    ys = [(k, y) for k, y in ys if len(y)]
    if len(ys) < 2:
        return None
    y = np.concatenate([y for _, y in ys])
    strata = ["/".join(k) for k, m in ys for _ in range(len(m))]
    learners = list(a.config.learners)
    key = ("+".join("/".join(k) for k, _ in ys), metric)
    iqm, poi = robust_cell(y, learners, a.config.reference, key, resamples, strata)
    envs = list(dict.fromkeys(e for e, _ in cells))
    return {"env": envs[0] if len(envs) == 1 else envs, "metric": metric, "n": len(y),
            "conditions": len(ys), "iqm": iqm, "poi": poi}  # fmt: skip


def analyse(
    config: BenchConfig,
    records: Sequence[RunRecord],
    metrics: Sequence[str] = METRICS,
    *,
    resamples: int | None = None,
) -> Analysis:
    """Descriptives, IQM and probability of improvement (bootstrap intervals, ``resamples``;
    None: ``robust.default_resamples()``), RM-ANOVA and post-hoc tests per env × condition ×
    metric; learning curves."""
    resamples = robust.default_resamples() if resamples is None else int(resamples)
    learners = list(config.learners)
    summary, posthoc, anova = [], [], []
    runs: dict[tuple[str, str, str], np.ndarray] = {}
    curves: dict[tuple[str, str, str], dict[str, np.ndarray]] = {}
    for exp in config.experiments:
        env, cond = exp.env, exp.condition.name
        for metric in metrics:
            _, y = _matrix(records, env, cond, learners, metric)
            if y.size == 0 or not np.isfinite(y).any():
                continue
            y = y[np.isfinite(y).all(axis=1)]  # listwise: paired tests need every learner's value
            runs[(env, cond, metric)] = y
            iqm, poi = (
                robust_cell(y, learners, config.reference, (env, cond, metric), resamples)
                if len(y)
                else (None, None)
            )
            for j, learner in enumerate(learners):
                summary.append(
                    {
                        "env": env,
                        "condition": cond,
                        "learner": learner,
                        "metric": metric,
                        **stats.describe(y[:, j]),
                        **_interval("iqm", iqm, j),
                    }
                )
            a = stats.rm_anova(y)
            anova.append({"env": env, "condition": cond, "metric": metric} | dataclasses.asdict(a))
            if len(learners) > 1:
                for row in stats.compare_to_reference(y, learners, config.reference):
                    row = {"env": env, "condition": cond, "metric": metric, **row}
                    row["plain_language"] = stats.plain_language(
                        display(row["learner"]),
                        display(row["baseline"]),
                        row["mean_diff"],
                        row["p_holm"],
                    )
                    row |= _interval("prob_improvement", poi, learners.index(row["baseline"]))
                    row["mark"] = stats.mark(row)
                    posthoc.append(row)
        for learner in learners:
            errs = [
                r["errors"]
                for r in records
                if (r["env"], r["condition"], r["learner"]) == (env, cond, learner)
            ]
            if not errs:
                continue
            width = max(len(e) for e in errs)
            arr = np.full((len(errs), width), np.nan)
            for i, e in enumerate(errs):
                arr[i, : len(e)] = [_f(v) for v in e]
            n = np.isfinite(arr).sum(axis=0)
            mean = np.nanmean(arr, axis=0)
            sd = np.array(
                [np.nanstd(c, ddof=1) if k > 1 else np.nan for c, k in zip(arr.T, n, strict=True)]
            )
            curves[(env, cond, learner)] = {
                "mean": mean,
                "sem": sd / np.sqrt(np.maximum(n, 1)),
                "n": n,
            }
    analysis = Analysis(config, summary, posthoc, anova, curves, [], runs=runs)
    analysis.resamples = resamples
    for env in dict.fromkeys(e.env for e in config.experiments):
        n_cond = sum(e.env == env for e in config.experiments)
        primary = env_preset(env).primary_metric
        if n_cond > 1 and len(learners) > 1 and primary in metrics:
            analysis.pooled.append(pooled_tests(records, [env], learners, primary))
    analysis.verdicts = paper_verdicts(analysis)
    for env in dict.fromkeys(e.env for e in config.experiments):
        for metric in analysis.metrics_for(env):
            conds = [(env, e.condition.name) for e in config.experiments if e.env == env]
            agg = aggregate(analysis, conds, metric, resamples)
            if agg is not None:
                analysis.aggregates.append(agg)
    return analysis


def _interval(name: str, iv: robust.Interval | None, j: int) -> dict[str, float]:
    """``name``, ``name_ci95_low``, ``name_ci95_high`` of column ``j`` (NaN without data)."""
    if iv is None:
        return {name: math.nan, f"{name}_ci95_low": math.nan, f"{name}_ci95_high": math.nan}
    return {
        name: float(iv.estimate[j]),
        f"{name}_ci95_low": float(iv.low[j]),
        f"{name}_ci95_high": float(iv.high[j]),
    }


def paper_verdicts(a: Analysis) -> list[dict[str, Any]]:
    """H1 and H2 per env, on the env's primary metric (Robot: regret; Highway: error).

    H1: in the training condition the reference learner is significantly lower than every
    baseline (paired t, Holm p < 0.05). H2: in every other paper condition no baseline is
    significantly lower than the reference (it is better or comparable).
    Only stated for the paper's comparison (``BenchConfig.is_paper``: its learners, reference,
    conditions, Tasks and correction counts); anything else gets tables and tests, no verdict.
    """
    out: list[dict[str, Any]] = []
    if not a.config.is_paper():
        return out
    ref = a.config.reference
    envs = list(dict.fromkeys(e.env for e in a.config.experiments))
    for env in envs:
        metric = env_preset(env).primary_metric
        for e in a.config.experiments:
            cond = e.condition.name
            if e.env != env:
                continue
            tests = [
                t
                for b in a.config.learners
                if b != ref and (t := a.test(env, cond, b, metric)) is not None
            ]
            if not tests:
                continue
            v: dict[str, Any] = {"env": env, "condition": cond, "metric": metric}
            v["hypothesis"] = "H1" if cond == "training" else "H2"
            for test in ("t", "wilcoxon"):
                dirs = {display(t["baseline"]): stats.direction(t, test) for t in tests}
                better = [b for b, d in dirs.items() if d < 0]
                worse = [b for b, d in dirs.items() if d > 0]
                if v["hypothesis"] == "H1":
                    holds = len(better) == len(dirs)
                    detail = (
                        f"{display(ref)} significantly lower than every baseline"
                        if holds
                        else "not significantly lower than "
                        + ", ".join(b for b in dirs if b not in better)
                    )
                else:
                    holds = not worse
                    detail = (
                        f"better than {', '.join(better) or 'none'}; "
                        f"worse than {', '.join(worse) or 'none'}"
                    )
                key = "" if test == "t" else "_wilcoxon"
                v["holds" + key], v["detail" + key] = holds, detail
            out.append(v)
    return out


# ---------------------------------------------------------------------- rendering
def fmt(x: float | None, digits: int = 3) -> str:
    """A table number: fixed digits, scientific for tiny non-zero values, 'n/a' for NaN/None."""
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{x:.{digits}f}" if abs(x) >= 10**-digits or x == 0 else f"{x:.1e}"


def fmt_ci(v: float | None, low: float | None, high: float | None, digits: int = 3) -> str:
    """'v [low, high]' with ``fmt``'s digits; '—' when there is no estimate."""
    if v is None:
        return "—"
    return f"{fmt(v, digits)} [{fmt(low, digits)}, {fmt(high, digits)}]"


def median_table(a: Analysis, env: str, metric: str) -> list[str]:
    """Markdown table of medians [Q1, Q3] (heavy-tailed metrics such as regret)."""
    learners = list(a.config.learners)
    conds = [e.condition.name for e in a.config.experiments if e.env == env]
    lines = ["| condition | " + " | ".join(display(learner) for learner in learners) + " |"]
    lines.append("|---|" + "---|" * len(learners))
    for cond in conds:
        cells = []
        for learner in learners:
            c = a.cell(env, cond, learner, metric)
            cells.append(
                "n/a" if c is None else f"{fmt(c['median'])} [{fmt(c['q1'])}, {fmt(c['q3'])}]"
            )
        lines.append(f"| {cond} | " + " | ".join(cells) + " |")
    return lines


def _ci(x: float, lo: float, hi: float) -> str:
    return f"{fmt(x)} [{fmt(lo)}, {fmt(hi)}]"


def _conditions(a: Analysis, env: str) -> list[tuple[str, str, str]]:
    return [(e.condition.name, env, e.condition.name) for e in a.config.experiments if e.env == env]


def iqm_table(
    a: Analysis,
    env: str,
    metric: str,
    rows: Sequence[tuple[str, str, str]] | None = None,
    agg: dict[str, Any] | None = None,
) -> list[str]:
    """Markdown table: rows conditions (or ``rows``: (label, env, condition)) and all of them
    (``agg``, by default the env's stratified aggregate), columns learners, 'IQM [95 % bootstrap
    CI]' with the reference's marks from the Wilcoxon signed-rank test (which, like the IQM,
    speaks of the typical run; the mean table's marks are the t-test's)."""
    learners = list(a.config.learners)

    def cell(e: str, cond: str, learner: str) -> str:
        c = a.cell(e, cond, learner, metric)
        if c is None or "iqm" not in c:
            return "n/a"
        mark = stats.mark(a.test(e, cond, learner, metric), "wilcoxon")
        return _ci(c["iqm"], c["iqm_ci95_low"], c["iqm_ci95_high"]) + mark

    head = [display(learner) for learner in learners]
    return _robust_table(a, env, metric, rows, agg, learners, head, cell, "iqm")


def poi_table(
    a: Analysis,
    env: str,
    metric: str,
    rows: Sequence[tuple[str, str, str]] | None = None,
    agg: dict[str, Any] | None = None,
) -> list[str]:
    """Markdown table: rows conditions (or ``rows``) and all of them, columns baselines,
    P(reference better than that baseline in a run) [95 % bootstrap CI]; [] without a
    reference to compare."""
    ref = a.config.reference
    bases = [learner for learner in a.config.learners if learner != ref]
    if not bases or ref not in a.config.learners:
        return []

    def cell(e: str, cond: str, b: str) -> str:
        t = a.test(e, cond, b, metric)
        if t is None or "prob_improvement" not in t:
            return "n/a"
        return _ci(*(t[k] for k in POI_KEYS))

    head = [f"vs {display(b)}" for b in bases]
    return _robust_table(a, env, metric, rows, agg, bases, head, cell, "poi")


def _robust_table(a, env, metric, rows, agg, columns, head, cell, key) -> list[str]:
    """The rows of ``iqm_table`` / ``poi_table``: one per (label, env, condition), then the
    aggregate's ``key`` interval for each of ``columns`` (learners)."""
    lines = ["| condition | " + " | ".join(head) + " |", "|---|" + "---|" * len(columns)]
    for label, e, cond in _conditions(a, env) if rows is None else rows:
        lines.append(f"| {label} | " + " | ".join(cell(e, cond, c) for c in columns) + " |")
    agg = _aggregate(a, env, metric) if agg is None and rows is None else agg
    if agg is not None and agg[key] is not None:
        iv, learners = agg[key], list(a.config.learners)
        cells = [_ci(iv.estimate[j], iv.low[j], iv.high[j]) for j in map(learners.index, columns)]
        lines.append(f"| all {agg['conditions']} (n = {agg['n']}) | " + " | ".join(cells) + " |")
    return lines


def _aggregate(a: Analysis, env: str, metric: str) -> dict[str, Any] | None:
    return next((g for g in a.aggregates if (g["env"], g["metric"]) == (env, metric)), None)


def robust_legend(reference: str, resamples: int | None = None, pooled: bool = True) -> str:
    """What the IQM and P(improvement) tables show, in one sentence (``pooled``: the tables
    have an 'all' row)."""
    boot = f"{resamples:,} resamples, " if resamples else ""
    strata = "; the 'all' row resamples within each condition" if pooled else ""
    return (
        "IQM = interquartile mean (the mean of the middle 50 % of the runs); P(improvement) = "
        f"the probability that {reference} is better than that learner in a run (paired runs, "
        "ties ½; 0.5 = neither is better in the typical run); [95 % CI]: percentile bootstrap "
        f"over run seeds ({boot}paired rows resampled together{strata})."
    )


def metric_table(a: Analysis, env: str, metric: str) -> list[str]:
    """Markdown table: rows conditions, columns learners, 'mean ± std' with the reference's
    directional marks (``stats.mark``)."""
    learners = list(a.config.learners)
    conds = [e.condition.name for e in a.config.experiments if e.env == env]
    head = "| condition | " + " | ".join(display(learner) for learner in learners) + " |"
    lines = [head, "|---|" + "---|" * len(learners)]
    for cond in conds:
        cells = []
        for learner in learners:
            c = a.cell(env, cond, learner, metric)
            if c is None:
                cells.append("n/a")
                continue
            mark = stats.mark(a.test(env, cond, learner, metric))
            cells.append(f"{fmt(c['mean'])} ± {fmt(c['std'])}{mark}")
        lines.append(f"| {cond} | " + " | ".join(cells) + " |")
    return lines


def summary_markdown(a: Analysis, meta: dict[str, Any], plots: Sequence[Path] = ()) -> str:
    cfg = a.config
    envs = list(dict.fromkeys(e.env for e in cfg.experiments))
    out = ["# strol-bench summary", ""]
    git = meta.get("git") or {}
    out += [
        f"- learners: {', '.join(display(learner) for learner in cfg.learners)}; "
        f"post-hoc reference: {display(cfg.reference)}",
        f"- config hash `{meta.get('config_hash')}`, git `{git.get('commit', 'n/a')}`"
        f"{' (uncommitted edits)' if git.get('dirty') else ''}, wall time "
        f"{fmt(meta.get('wall_time_s', math.nan), 1)} s",
        "- cells: mean ± std over runs, or IQM [95 % CI]. Marks: "
        + stats.mark_legend(display(cfg.reference))
        + "; in the IQM tables the same marks come from the Wilcoxon signed-rank test (Holm). "
        "Lower is better.",
        f"- {robust_legend(display(cfg.reference), a.resamples)}",
        "",
    ]
    if a.verdicts:
        out += ["## Hypotheses", ""]
        for v in a.verdicts:
            word = "HOLDS" if v["holds"] else "FAILS"
            wil = "holds" if v["holds_wilcoxon"] else "fails"
            out.append(
                f"- **{v['hypothesis']} {v['env']} / {v['condition']} ({v['metric']}): "
                f"{word}** (paired t, Holm) — {v['detail']}. Wilcoxon signed-rank (Holm): "
                f"{wil} — {v['detail_wilcoxon']}"
            )
        out.append("")
    for env in envs:
        preset = env_preset(env)
        out += [f"## {preset.env_id}", ""]
        for e in cfg.experiments:
            if e.env == env:
                out.append(
                    f"- {e.condition.name}: {e.condition.describe()}; {e.runs} runs "
                    f"(seeds {e.seeds.start}–{e.seeds.stop - 1}), {e.corrections} corrections"
                )
        out.append("")
        metrics = a.metrics_for(env)
        primary = preset.primary_metric if preset.primary_metric in metrics else metrics[0]
        for metric in [primary] + [m for m in metrics if m != primary]:
            tag = " — primary metric" if metric == primary else ""
            out += [f"### {METRIC_LABELS[metric]}{tag}", ""]
            out += metric_table(a, env, metric)
            out.append("")
            out += [f"IQM [95 % CI] of {metric}:", "", *iqm_table(a, env, metric), ""]
            poi = poi_table(a, env, metric)
            if poi:
                ref = display(cfg.reference)
                out += [f"P({ref} better in a run) [95 % CI] on {metric}:", "", *poi, ""]
            if metric == primary:
                out += [f"Median [Q1, Q3] of {metric}:", ""]
                out += median_table(a, env, metric)
                out.append("")
        from strol_gym.benchmarks.analysis.paper_numbers import PAPER, side_by_side

        baselines = set(PAPER_LEARNERS) - {REFERENCE_LEARNER}
        if (env, primary) in PAPER and set(cfg.learners) & baselines:
            out += [
                f"### {primary} beside the authors' reported numbers (their repository's tables, "
                "from their released code; not a target)",
                "",
                *side_by_side(a, env, primary, cfg.learners),
                "",
            ]
        out += [f"### Tests on {primary}", ""]
        for e in cfg.experiments:
            if e.env != env:
                continue
            cond = e.condition.name
            an = next(
                (
                    r
                    for r in a.anova
                    if (r["env"], r["condition"], r["metric"]) == (env, cond, primary)
                ),
                None,
            )
            if an is not None:
                line = stats.AnovaResult.from_row(an).line()
                out.append(f"- **{cond}**: repeated-measures ANOVA across learners: {line}")
            for t in a.posthoc:
                if (t["env"], t["condition"], t["metric"]) == (env, cond, primary):
                    wil = stats.format_p(t["wilcoxon_p_holm"])
                    p_better = _ci(
                        t["prob_improvement"],
                        t["prob_improvement_ci95_low"],
                        t["prob_improvement_ci95_high"],
                    )
                    out.append(
                        f"  - {t['plain_language']}; Δ = {fmt(t['mean_diff'])} "
                        f"[{fmt(t['ci95_low'])}, {fmt(t['ci95_high'])}], "
                        f"d_z = {t['effect_size']:.2f}, Wilcoxon {wil}{_wilcoxon_mark(t)}; "
                        f"P({display(t['learner'])} better in a run) = {p_better}"
                    )
        for pooled in a.pooled:
            if pooled["envs"] == [env]:
                out += [
                    "",
                    f"Whole experiment ({pooled['metric']}: each run seed's mean over the "
                    f"{sum(e.env == env for e in cfg.experiments)} conditions, n = "
                    f'{pooled["n"]}; the paper\'s test "across all trials and conditions"):',
                    "",
                    *pooled_lines(pooled),
                ]
        out.append("")
    if plots:
        out += ["## Plots", ""] + [f"- ![{p.stem}]({p})" for p in plots if p.suffix == ".png"]
        out.append("")
    return "\n".join(out)


def _wilcoxon_mark(t: dict[str, Any]) -> str:
    m = stats.mark(t, "wilcoxon")
    return f" ({m})" if m else ""


def write_reports(
    rd: ResultsDir, *, plots: bool = True, resamples: int | None = None
) -> tuple[Analysis, list[Path]]:
    """Read the records of ``rd`` and (re)write every table, summary.md and the plots."""
    records = rd.read_records()
    if not records:
        raise ValueError(f"{rd.path} holds no finished runs yet")
    rd.write_run_tables(records)
    a = analyse(rd.config, records, resamples=resamples)
    write_csv(rd.path / "summary.csv", a.summary, SUMMARY_COLUMNS)
    write_csv(rd.path / "stats.csv", a.posthoc, STATS_COLUMNS)
    write_csv(rd.path / "anova.csv", a.anova, ANOVA_COLUMNS)
    paths: list[Path] = []
    if plots:
        from strol_gym.benchmarks.analysis import plots as plotting

        paths = plotting.make_plots(a, rd.path / "plots")
    rel = [p.relative_to(rd.path) for p in paths]
    write_text_atomic(rd.path / "summary.md", summary_markdown(a, rd.meta, rel))
    return a, paths


def console_summary(a: Analysis) -> str:
    """The primary-metric tables and the verdicts, for the terminal."""
    out = []
    for env in dict.fromkeys(e.env for e in a.config.experiments):
        metrics = a.metrics_for(env)
        if not metrics:
            continue
        primary = env_preset(env).primary_metric
        primary = primary if primary in metrics else metrics[0]
        ref = display(a.config.reference)
        out += [f"{env_preset(env).env_id}: {METRIC_LABELS[primary]} (mean ± std)"]
        out += [*metric_table(a, env, primary), ""]
        out += [f"IQM [95 % CI] of {primary}:", *iqm_table(a, env, primary), ""]
        out += [f"P({ref} better in a run) [95 % CI]:", *poi_table(a, env, primary), ""]
    if a.config.reference in a.config.learners:
        ref = display(a.config.reference)
        out += [f"Marks beside means: {stats.mark_legend(ref)}; beside IQMs: the same from the "
                "Wilcoxon signed-rank test.", ""]  # fmt: skip
    for v in a.verdicts:
        out.append(
            f"{v['hypothesis']} {v['env']}/{v['condition']} ({v['metric']}): "
            f"{'holds' if v['holds'] else 'FAILS'} — {v['detail']}"
        )
    return "\n".join(out)
