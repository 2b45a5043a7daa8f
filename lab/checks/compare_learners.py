"""Paired tests of candidate learners against StROL and against the best paper baseline.

    .venv/bin/python -m lab.checks.compare_learners results/learners-robot [...]
        [--learners bayes,bayes-teacher,strol-adaptive,strol-unrolled] [--metrics regret,error]

Reads ``runs.csv`` of ``strol-bench`` results folders and prints, per env and condition, a
markdown table: for each candidate learner and metric (regret where the env has it, error,
1 − cos), Δ = candidate − other (mean of the paired differences; negative = candidate lower)
against StROL and against the *best baseline* of that condition (the paper baseline — Gradient,
One, MOF, e2e — with the lowest mean of that metric), with the paired t-test and the Wilcoxon
signed-rank test. Holm runs per env × condition × metric over the 2 × (number of candidates)
comparisons, separately for each test. Marks (``stats.signed_stars``): ↓ the candidate
significantly lower than the other, ↑ higher (the t-test's by the mean difference, the
Wilcoxon test's by the Hodges–Lehmann estimate); * p < 0.05, ** < 0.01, *** < 0.001 (Holm).
P(better): the probability that the candidate beats the other in a paired run (ties ½), with
its 95 % bootstrap interval over run seeds (``analysis.robust``).
"""

from __future__ import annotations

import argparse
import csv
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from strol_gym.benchmarks.analysis.robust import cell_rng, poi_interval
from strol_gym.benchmarks.analysis.stats import holm, paired_test, signed_stars
from strol_gym.benchmarks.engine.conditions import REFERENCE_LEARNER as REFERENCE
from strol_gym.metrics import RUN_METRICS

BASELINES = ("gradient", "one", "mof", "e2e")
CANDIDATES = ("bayes", "bayes-teacher", "strol-adaptive", "strol-unrolled")
METRICS = RUN_METRICS


def load_runs(folder: Path) -> dict[tuple[str, str, str], dict[int, dict[str, float]]]:
    """(env, condition, learner) -> seed -> {metric: value}."""
    out: dict = defaultdict(dict)
    with open(folder / "runs.csv", newline="") as f:
        for row in csv.DictReader(f):
            key = (row["env"], row["condition"], row["learner"])
            out[key][int(row["seed"])] = {m: float(row[m]) for m in METRICS}
    return out


def _paired(runs, env, cond, a, b, metric):
    seeds = sorted(set(runs[(env, cond, a)]) & set(runs[(env, cond, b)]))
    x = np.array([runs[(env, cond, a)][s][metric] for s in seeds])
    y = np.array([runs[(env, cond, b)][s][metric] for s in seeds])
    return x, y


def compare(runs, candidates, wanted=METRICS) -> list[str]:
    """The markdown lines for every (env, condition) in ``runs``, for the ``wanted`` metrics
    that the reference learner has (regret is NaN where a Task has no planner)."""
    lines = []
    for env, cond in dict.fromkeys((e, c) for e, c, _ in runs):
        metrics = [
            m
            for m in wanted
            if all(math.isfinite(v[m]) for v in runs[(env, cond, REFERENCE)].values())
        ]
        lines += [
            f"**{env} / {cond}** (Δ = candidate − other, mean of paired differences; "
            "t / W = Holm-adjusted p of the paired t and Wilcoxon tests)",
            "",
            "| learner | metric | mean ± sd | vs StROL: Δ | t | W | P(better) | best baseline | Δ "
            "| t | W | P(better) |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for metric in metrics:
            means = {
                b: np.mean([v[metric] for v in runs[(env, cond, b)].values()]) for b in BASELINES
            }
            best = min(means, key=means.__getitem__)
            tests, pois = [], []
            for cand in candidates:
                for other in (REFERENCE, best):
                    x, y = _paired(runs, env, cond, cand, other, metric)
                    tests.append(paired_test(x, y))
                    rng = cell_rng(env, cond, metric, cand, other)
                    pois.append(poi_interval(np.column_stack([x, y]), 0, rng=rng))
            p_t = holm([t.p_t for t in tests])
            p_w = holm([t.p_wilcoxon for t in tests])
            for i, cand in enumerate(candidates):
                vals = np.array([v[metric] for v in runs[(env, cond, cand)].values()])
                cells = [cand, metric, f"{vals.mean():.3g} ± {vals.std(ddof=1):.3g}"]
                for j, name in ((2 * i, None), (2 * i + 1, best)):
                    t = tests[j]
                    if name is not None:
                        cells.append(f"{name} ({means[best]:.3g})")
                    poi = pois[j]
                    cells += [
                        f"{t.mean_diff:+.3g}",
                        f"{p_t[j]:.2g}{signed_stars(t.mean_diff, p_t[j])}",
                        f"{p_w[j]:.2g}{signed_stars(t.hl_diff, p_w[j])}",
                        f"{poi.estimate[1]:.2f} [{poi.low[1]:.2f}, {poi.high[1]:.2f}]",
                    ]
                lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folders", nargs="+", type=Path, help="strol-bench results folders")
    parser.add_argument("--learners", default=",".join(CANDIDATES))
    parser.add_argument("--metrics", default=",".join(METRICS), help="subset of " + str(METRICS))
    args = parser.parse_args()
    wanted = [m.strip() for m in args.metrics.split(",") if m.strip()]
    if not wanted or set(wanted) - set(METRICS):
        parser.error(f"--metrics must name some of {METRICS}, got {args.metrics!r}")
    candidates = [c.strip() for c in args.learners.split(",") if c.strip()]
    for folder in args.folders:
        runs = load_runs(folder)
        print("\n".join(compare(runs, candidates, wanted)))


if __name__ == "__main__":
    main()
