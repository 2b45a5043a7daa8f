"""``strol-bench confirm``: the pre-registered confirmatory tests.

``--protocol paper-conditions`` (the default) is the Robot test of docs/confirmatory.md;
``--protocol held-out`` is protocol 1 of docs/confirmatory-held-out.md: the same analysis on
cells env × held-out human (Boltzmann, myopic, driver), 1000 runs each on seeds 3_200_000 –
3_200_999, primary outcome regret on the Robot and 1 − cos on the Highway.

The first protocol is implemented as written and nothing else: 1000 paired runs per paper
condition on
seeds 3_000_000 – 3_000_999, Gradient, One, MOF and StROL; primary outcome regret; the two-sided
Wilcoxon signed-rank test of StROL against each baseline after the tie rule (|d| ≤ 1e-6 -> 0),
Holm over the three baselines per condition, direction from the signed ranks; verdicts
confirmed / not confirmed / contradicted per condition; secondary paired t-tests, error,
1 − cos and bootstrap effect sizes. Other ``--seed`` or ``--runs`` values give an exploratory
run, labelled as such (the tests use those, never the protocol's seeds).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from strol_gym.benchmarks.analysis import robust, stats
from strol_gym.benchmarks.analysis.report import fmt, fmt_ci
from strol_gym.benchmarks.args import nonneg_int, positive_int
from strol_gym.benchmarks.engine.conditions import (
    CONDITION_NAMES,
    REFERENCE_LEARNER,
    Condition,
    env_preset,
    make_condition,
)
from strol_gym.benchmarks.engine.config import DEFAULT_BLOCK, BenchConfig, Experiment
from strol_gym.benchmarks.engine.record import RunRecord
from strol_gym.benchmarks.experiments.base import BenchExperiment, Outcome, load
from strol_gym.lazy import LazyModule

if TYPE_CHECKING:
    from scipy import stats as sps
else:  # scipy loads on first use: `strol-bench --help` does not need it
    sps = LazyModule("scipy.stats")

PROTOCOL_RUNS = 1000
PROTOCOL_SEED = 3_000_000
REFERENCE = REFERENCE_LEARNER
"""The pre-registered reference learner, "strol" (tests pin it: the protocol fixes it)."""
BASELINES = ("gradient", "one", "mof")
LEARNERS = (*BASELINES, REFERENCE)
PRIMARY = "regret"
SECONDARY = ("error", "cos_error")
TIE_TOL = 1e-6
"""Regret differences with |d| ≤ this are ties (0): floating-point dust of the planner."""
ALPHA = 0.05
RESAMPLES = 10_000
BOOTSTRAP_SEED = 20240610
SWITCH_REGRET = 0.3
"""Regret at or above this counts as a "regime switch" run (descriptive only)."""

COLUMNS = (
    "condition",
    "metric",
    "baseline",
    "n",
    "n_nonzero",
    "r_minus",
    "r_plus",
    "wilcoxon_p_raw",
    "wilcoxon_p_holm",
    "outcome",
    "wilcoxon_p_raw_no_tie_rule",
    "wilcoxon_p_holm_12",
    "t_mean_diff",
    "t_ci95_low",
    "t_ci95_high",
    "t_p_raw",
    "t_p_holm",
    "cohen_dz",
    "median_diff",
    "median_diff_ci95_low",
    "median_diff_ci95_high",
    "prob_improvement",
    "prob_improvement_ci95_low",
    "prob_improvement_ci95_high",
)


PROTOCOLS = ("paper-conditions", "held-out")
"""docs/confirmatory.md and docs/confirmatory-held-out.md (protocol 1)."""
HELD_OUT_SEED = 3_200_000
HELD_OUT_HUMANS = ("boltzmann", "myopic", "driver")
"""Protocol 1's humans: none is the eq. M6 teacher that every shipped Robot/Highway ĝ saw."""
HELD_OUT_ENVS = ("robot", "highway")
HELD_OUT_PRIMARY = {"robot": "regret", "highway": "cos_error"}
"""The scale-free primary outcome per env (the Highway Task has no planner, so no regret)."""


def make_config(env: str = "robot", *, runs: int = PROTOCOL_RUNS, seed: int = PROTOCOL_SEED):
    """The protocol's config: the four paper conditions, the four learners, the default block."""
    exps = tuple(
        Experiment(env, make_condition(env, c), runs=runs, seed=seed) for c in CONDITION_NAMES
    )
    return BenchConfig(exps, LEARNERS, REFERENCE, DEFAULT_BLOCK)


def held_out_condition(env: str, human: str) -> Condition:
    """A held-out cell: ``human`` at its defaults, the env's training σ, ε = 0, bimodal prior."""
    sigma = env_preset(env).training_sigma
    return Condition(human, sigma=sigma, bias=0.0, prior="bimodal", human=human)


def make_held_out_config(
    envs: Sequence[str] = HELD_OUT_ENVS, *, runs: int = PROTOCOL_RUNS, seed: int = HELD_OUT_SEED
) -> BenchConfig:
    """Protocol 1's config: env × held-out human, the four learners, the default block."""
    exps = tuple(
        Experiment(env, held_out_condition(env, h), runs=runs, seed=seed)
        for env in envs
        for h in HELD_OUT_HUMANS
    )
    return BenchConfig(exps, LEARNERS, REFERENCE, DEFAULT_BLOCK)


def is_protocol(runs: int, seed: int, protocol: str = "paper-conditions") -> bool:
    first = PROTOCOL_SEED if protocol == "paper-conditions" else HELD_OUT_SEED
    return int(runs) == PROTOCOL_RUNS and int(seed) == first


# ---------------------------------------------------------------------- the analysis
def tie_rule(d: np.ndarray, metric: str) -> np.ndarray:
    """Regret differences with |d| ≤ TIE_TOL become 0; other metrics are left as they are."""
    d = np.asarray(d, dtype=np.float64)
    return np.where(np.abs(d) <= TIE_TOL, 0.0, d) if metric == PRIMARY else d


def signed_rank(d: np.ndarray) -> dict[str, float]:
    """Two-sided Wilcoxon signed-rank test, zeros discarded, with the rank sums R− and R+."""
    nz = d[d != 0]
    if len(nz) == 0:
        return {"n_nonzero": 0, "r_minus": 0.0, "r_plus": 0.0, "p": 1.0}
    ranks = sps.rankdata(np.abs(nz))
    res = sps.wilcoxon(d, zero_method="wilcox", alternative="two-sided")
    return {
        "n_nonzero": len(nz),
        "r_minus": float(ranks[nz < 0].sum()),
        "r_plus": float(ranks[nz > 0].sum()),
        "p": float(res.pvalue),
    }


def outcome(p_holm: float, r_minus: float, r_plus: float) -> str:
    """The protocol's per-comparison outcome."""
    if math.isfinite(p_holm) and p_holm < ALPHA and r_minus != r_plus:
        return "StROL lower" if r_minus > r_plus else "StROL higher"
    return "no significant difference"


def verdict(outcomes: Sequence[str]) -> str:
    """confirmed (lower than all three), contradicted (higher than one), else not confirmed."""
    if all(o == "StROL lower" for o in outcomes):
        return "confirmed"
    if any(o == "StROL higher" for o in outcomes):
        return "contradicted"
    return "not confirmed"


def analyse(
    records: Sequence[RunRecord],
    env: str = "robot",
    conditions: Sequence[str] = CONDITION_NAMES,
    *,
    resamples: int = RESAMPLES,
    boot_seed: int = BOOTSTRAP_SEED,
    primary: str = PRIMARY,
) -> dict[str, Any]:
    """The protocol's analysis of the per-run records: test rows, verdicts, descriptives.
    ``primary`` is the verdicts' outcome (held-out Highway: 1 − cos); the others are secondary.
    Rows carry ``env``; the 12-test sensitivity spans this call's conditions."""
    from strol_gym.benchmarks.analysis.base import _matrix

    metrics = (primary, *[m for m in (PRIMARY, *SECONDARY) if m != primary])
    if env == "highway":  # no planner, no regret
        metrics = tuple(m for m in metrics if m != "regret")
    rng = np.random.default_rng(boot_seed)
    learners = list(LEARNERS)
    r = learners.index(REFERENCE)
    rows: list[dict[str, Any]] = []
    descriptives: list[dict[str, Any]] = []
    verdicts: dict[str, str] = {}
    for cond in conditions:
        ys = {}
        for metric in metrics:
            _, y = _matrix(records, env, cond, learners, metric)
            ys[metric] = y[np.isfinite(y).all(axis=1)]
            for j, learner in enumerate(learners):
                row: dict[str, Any] = {
                    "env": env,
                    "condition": cond,
                    "learner": learner,
                    "metric": metric,
                }
                row |= stats.describe(ys[metric][:, j])
                if metric == PRIMARY:
                    row["n_switch"] = int((ys[metric][:, j] >= SWITCH_REGRET).sum())
                descriptives.append(row)
            if len(ys[metric]):
                # a generator of its own: the protocol's bootstrap stream below stays as it was
                iv = robust.iqm_interval(
                    ys[metric],
                    rng=robust.cell_rng("confirm", env, cond, metric),
                    resamples=robust.default_resamples(),
                )
                for j, row in enumerate(descriptives[-len(learners) :]):
                    row |= {"iqm": float(iv.estimate[j]), "iqm_ci95_low": float(iv.low[j]),
                            "iqm_ci95_high": float(iv.high[j])}  # fmt: skip
        n = len(ys[primary])
        idx = robust.bootstrap_indices(n, int(resamples), rng) if n else np.zeros((0, 0), int)
        for metric in metrics:
            y = ys[metric]
            block: list[dict[str, Any]] = []
            for b in BASELINES:
                j = learners.index(b)
                raw = y[:, r] - y[:, j]
                d = tie_rule(raw, metric)
                sr = signed_rank(d)
                pt = stats.paired_test(y[:, r], y[:, j])
                imp = robust.improvement(d, np.zeros_like(d))  # d after the tie rule
                if len(d) and len(idx):
                    med_ci = np.percentile(np.median(d[idx], axis=1), [2.5, 97.5])
                    poi_ci = np.percentile(imp[idx].mean(axis=1), [2.5, 97.5])
                else:
                    med_ci = poi_ci = (math.nan, math.nan)
                block.append(
                    {
                        "env": env,
                        "condition": cond,
                        "metric": metric,
                        "baseline": b,
                        "n": len(d),
                        "n_nonzero": sr["n_nonzero"],
                        "r_minus": sr["r_minus"],
                        "r_plus": sr["r_plus"],
                        "wilcoxon_p_raw": sr["p"],
                        "wilcoxon_p_raw_no_tie_rule": pt.p_wilcoxon,
                        "t_mean_diff": pt.mean_diff,
                        "t_ci95_low": pt.ci_low,
                        "t_ci95_high": pt.ci_high,
                        "t_p_raw": pt.p_t,
                        "cohen_dz": pt.d_z,
                        "median_diff": float(np.median(d)) if len(d) else math.nan,
                        "median_diff_ci95_low": float(med_ci[0]),
                        "median_diff_ci95_high": float(med_ci[1]),
                        "prob_improvement": float(imp.mean()) if len(d) else math.nan,
                        "prob_improvement_ci95_low": float(poi_ci[0]),
                        "prob_improvement_ci95_high": float(poi_ci[1]),
                    }
                )
            for row, ph, th in zip(
                block,
                stats.holm([x["wilcoxon_p_raw"] for x in block]),
                stats.holm([x["t_p_raw"] for x in block]),
                strict=True,
            ):
                row["wilcoxon_p_holm"], row["t_p_holm"] = float(ph), float(th)
                row["outcome"] = outcome(float(ph), row["r_minus"], row["r_plus"])
            rows += block
        verdicts[cond] = verdict(
            [x["outcome"] for x in rows if x["condition"] == cond and x["metric"] == primary]
        )
    prim = [x for x in rows if x["metric"] == primary]
    sensitivity = holm_sensitivity(prim, "condition", conditions)
    return {
        "primary": primary,
        "rows": rows,
        "descriptives": descriptives,
        "verdicts": verdicts,
        "verdicts_holm_12": sensitivity,
    }


def holm_sensitivity(prim: list[dict], key: str, keys: Iterable[str]) -> dict[str, str]:
    """The stated sensitivity check: Holm over every primary test row in ``prim`` (written to
    ``wilcoxon_p_holm_12``, the column's name whatever the count), and the verdict per ``key``
    value (a condition, or a held-out "env/human" cell) under it."""
    for row, p in zip(prim, stats.holm([x["wilcoxon_p_raw"] for x in prim]), strict=True):
        row["wilcoxon_p_holm_12"] = float(p)
    return {
        k: verdict(
            [
                outcome(x["wilcoxon_p_holm_12"], x["r_minus"], x["r_plus"])
                for x in prim
                if x[key] == k
            ]
        )
        for k in keys
    }


# ---------------------------------------------------------------------- the command
class Confirm(BenchExperiment):
    """the pre-registered confirmatory tests (docs/confirmatory.md; --protocol held-out:
    docs/confirmatory-held-out.md)

    Runs exactly a protocol. --seed/--runs other than the protocol's make an exploratory run
    (for tests), labelled as such.
    """

    name = "confirm"
    columns: tuple[str, ...] = COLUMNS

    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--protocol",
            choices=PROTOCOLS,
            default="paper-conditions",
            help="paper-conditions: docs/confirmatory.md (Robot); held-out: protocol 1 of "
            "docs/confirmatory-held-out.md (Boltzmann, myopic, driver; Robot and Highway)",
        )
        p.add_argument(
            "--env",
            choices=(*HELD_OUT_ENVS, "all"),
            default=None,
            help="paper-conditions: robot (its only env); held-out: robot, highway or all "
            "(default)",
        )
        p.add_argument(
            "--runs",
            type=positive_int("--runs"),
            default=PROTOCOL_RUNS,
            help=f"runs per condition (protocol: {PROTOCOL_RUNS})",
        )
        p.add_argument(
            "--seed",
            type=nonneg_int("--seed"),
            default=None,
            help=f"first run seed (protocols: {PROTOCOL_SEED}, held-out {HELD_OUT_SEED}; tests "
            "use other seeds)",
        )
        p.add_argument("--jobs", type=positive_int("--jobs"), default=None, help="worker processes")
        p.add_argument(
            "--out",
            default=None,
            help="results folder (default results/confirm-<env>, results/confirm-held-out)",
        )
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        p.add_argument("--force", action="store_true", help="replace a folder of another config")
        p.add_argument("--no-plots", action="store_true")

    def _envs(self, args: argparse.Namespace) -> list[str]:
        if args.protocol == "paper-conditions":
            if args.env not in (None, "robot"):
                raise ValueError(
                    f"--env must be robot for --protocol paper-conditions, got {args.env!r}"
                )
            return ["robot"]
        return list(HELD_OUT_ENVS) if args.env in (None, "all") else [args.env]

    def default_out(self, args: argparse.Namespace) -> str:
        if args.protocol == "held-out":
            envs = self._envs(args)
            return "results/confirm-held-out" + ("" if len(envs) > 1 else f"-{envs[0]}")
        return "results/confirm-robot"

    def plan(self, args: argparse.Namespace) -> BenchConfig:
        self._t0 = time.perf_counter()
        envs = self._envs(args)
        if args.protocol == "held-out":
            if args.seed is None:
                args.seed = HELD_OUT_SEED
            self.columns = ("env", *COLUMNS)
            return make_held_out_config(envs, runs=args.runs, seed=args.seed)
        if args.seed is None:
            args.seed = PROTOCOL_SEED
        self.columns = COLUMNS
        return make_config(envs[0], runs=args.runs, seed=args.seed)

    def execute(self, config: BenchConfig, args: argparse.Namespace, out: Path) -> Outcome:
        protocol = is_protocol(args.runs, args.seed, args.protocol)
        rd, _, run_wall = self.run(config, out, args)
        records = rd.read_records()
        if args.protocol == "held-out":
            result = analyse_held_out(records, self._envs(args))
        else:
            result = analyse(records, "robot")
        wall = time.perf_counter() - self._t0
        doc = (
            "docs/confirmatory.md"
            if args.protocol == "paper-conditions"
            else ("docs/confirmatory-held-out.md, protocol 1")
        )
        label = (
            f"PRE-REGISTERED confirmatory run ({doc})"
            if protocol
            else "EXPLORATORY run (not the pre-registered seeds or run count; no confirmatory "
            "claim)"
        )
        seeds = [config.experiments[0].seeds.start, config.experiments[0].seeds.stop - 1]
        md = markdown(result, label, seeds, rd.meta, args.protocol)
        meta = {
            "protocol": protocol,
            "protocol_name": args.protocol,
            "config": config.to_dict(),
            "seeds": seeds,
            "tie_tol": TIE_TOL,
            "alpha": ALPHA,
            "bootstrap": {"resamples": RESAMPLES, "seed": BOOTSTRAP_SEED},
            "code_fingerprint": rd.meta.get("extra", {}).get("code"),
            "verdicts": result["verdicts"],
            "verdicts_holm_12": result["verdicts_holm_12"],
            "wall_time_s": {"total": wall, "episodes": run_wall},
        }
        if args.protocol == "paper-conditions":  # the published meta's keys, unchanged
            del meta["protocol_name"]
        line = (
            f"\nwall time {wall:.1f} s (episodes {run_wall:.1f} s; {load()}); results in {rd.path}/"
        )
        return Outcome(rd.path, md, result["rows"], meta, line, state=result)

    def plot(self, outcome: Outcome, folder: Path) -> list[Path]:
        return plot(outcome.state, folder)


def analyse_held_out(
    records: Sequence[RunRecord], envs: Sequence[str], *, resamples: int = RESAMPLES
) -> dict[str, Any]:
    """Protocol 1: ``analyse`` per env on its held-out cells with its primary outcome; verdict
    keys are "env/human"; the sensitivity check is Holm over every cell's three tests."""
    rows: list[dict[str, Any]] = []
    descriptives: list[dict[str, Any]] = []
    verdicts: dict[str, str] = {}
    for env in envs:
        r = analyse(
            records, env, HELD_OUT_HUMANS, primary=HELD_OUT_PRIMARY[env], resamples=resamples
        )
        for x in (*r["rows"], *r["descriptives"]):
            x["cell"] = f"{env}/{x['condition']}"
        rows += r["rows"]
        descriptives += r["descriptives"]
        verdicts |= {f"{env}/{c}": v for c, v in r["verdicts"].items()}
    prim = [x for x in rows if x["metric"] == HELD_OUT_PRIMARY[x["env"]]]
    sensitivity = holm_sensitivity(prim, "cell", verdicts)
    return {
        "primary": HELD_OUT_PRIMARY,
        "rows": rows,
        "descriptives": descriptives,
        "verdicts": verdicts,
        "verdicts_holm_12": sensitivity,
    }


def _primary_row(result: dict, key: str, baseline: str) -> dict:
    """The primary-outcome test row of a verdict key (a condition, or "env/human")."""
    for r in result["rows"]:
        where = r.get("cell", r["condition"])
        prim = result["primary"]
        metric = prim[r["env"]] if isinstance(prim, dict) else prim
        if (where, r["metric"], r["baseline"]) == (key, metric, baseline):
            return r
    raise KeyError(f"no primary row for {key} vs {baseline}")


def _verdict_lines(result: dict) -> list[str]:
    """One bullet per verdict key: the verdict and each baseline's outcome and Holm p."""
    from strol_gym.benchmarks.analysis.report import display

    lines = []
    for key, v in result["verdicts"].items():
        rows = [_primary_row(result, key, b) for b in BASELINES]
        outs = [
            f"{display(r['baseline'])}: {r['outcome']} (Holm p = {fmt(r['wilcoxon_p_holm'], 4)})"
            for r in rows
        ]
        lines.append(f"- **{key}: {v.upper()}** — " + "; ".join(outs))
    return lines


def _sensitivity_line(result: dict) -> str:
    """The report's line on the Holm-over-every-comparison check."""
    changed = {c: v for c, v in result["verdicts_holm_12"].items() if v != result["verdicts"][c]}
    n_tests = len(BASELINES) * len(result["verdicts"])
    return f"Sensitivity (Holm over all {n_tests} comparisons): " + (
        "no verdict changes."
        if not changed
        else "; ".join(f"{c} would be {v}" for c, v in changed.items())
    )


def _test_rows(result: dict, key: str) -> list[str]:
    """One markdown row per test row, first column ``key`` (condition or cell)."""
    from strol_gym.benchmarks.analysis.report import display

    return [
        f"| {x[key]} | {x['metric']} | {display(x['baseline'])} | "
        f"{fmt(x['wilcoxon_p_holm'], 4)}"
        f"{stats.signed_stars(x['r_plus'] - x['r_minus'], x['wilcoxon_p_holm'])} | "
        f"{x['r_minus']:.0f} / {x['r_plus']:.0f} | "
        f"{x['outcome']} | {fmt(x['median_diff'])} [{fmt(x['median_diff_ci95_low'])}, "
        f"{fmt(x['median_diff_ci95_high'])}] | {fmt(x['prob_improvement'])} "
        f"[{fmt(x['prob_improvement_ci95_low'])}, {fmt(x['prob_improvement_ci95_high'])}] | "
        f"{fmt(x['t_mean_diff'])} [{fmt(x['t_ci95_low'])}, {fmt(x['t_ci95_high'])}], "
        f"{fmt(x['t_p_holm'], 4)}{stats.signed_stars(x['t_mean_diff'], x['t_p_holm'])}, "
        f"{fmt(x['cohen_dz'], 2)} |"
        for x in result["rows"]
    ]


TESTS_HEAD = (
    "| metric | vs | Wilcoxon p (Holm) | R− / R+ | outcome | median diff [95 % CI] "
    "| P(improvement) [95 % CI] | paired t: Δ [95 % CI], p (Holm), d_z |"
)


def markdown(
    result: dict, label: str, seeds: list[int], meta: dict, protocol: str = "paper-conditions"
) -> list[str]:
    """The report of either protocol: verdicts, descriptives per learner, every test row."""
    if protocol == "held-out":
        return markdown_held_out(result, label, seeds, meta)

    def cell(x: dict) -> str:
        iqm = fmt_ci(x.get("iqm"), x.get("iqm_ci95_low"), x.get("iqm_ci95_high"))
        return f"{fmt(x['mean'])} ± {fmt(x['std'])}; {fmt(x['median'])}; {iqm}; {x['n_switch']}"

    return _report(
        result,
        seeds,
        meta,
        title=f"Confirmatory Robot test — {label}",
        key="condition",
        primary="",
        verdicts="primary: regret, two-sided Wilcoxon, Holm over 3 per condition",
        table="Regret per learner (mean ± std; median; IQM [95 % CI]; runs with regret ≥ 0.3)",
        metric=lambda _: PRIMARY,
        cell=cell,
        footer=f"Outcomes other than regret are secondary (no verdict). Ties: |d| ≤ {TIE_TOL:g} "
        f"on regret. Bootstrap: {RESAMPLES} paired resamples, seed {BOOTSTRAP_SEED} (the IQM's: "
        f"{robust.default_resamples()}, its own generator per condition). Marks beside the "
        "Wilcoxon p (direction from R− / R+) and beside the paired t's p: "
        + stats.mark_legend("StROL", "wilcoxon").replace(" (Wilcoxon signed-rank, Holm", " (Holm")
        + ". "
        "IQM = interquartile mean (the mean of the middle 50 % of the runs).",
    )


def markdown_held_out(result: dict, label: str, seeds: list[int], meta: dict) -> list[str]:
    """The held-out protocol's report: verdicts per cell, descriptives, every test row."""
    from strol_gym.benchmarks.analysis.base import METRIC_LABELS

    prim = result["primary"]

    def cell(x: dict) -> str:
        return (
            f"{fmt(x['mean'])} ± {fmt(x['std'])}; {fmt(x['median'])} "
            f"[{fmt(x['q1'])}, {fmt(x['q3'])}]"
        )

    return _report(
        result,
        seeds,
        meta,
        title=f"Confirmatory test with held-out humans — {label}",
        key="cell",
        primary=" Primary outcome: "
        + ", ".join(f"{env} {METRIC_LABELS.get(m, m)}" for env, m in prim.items())
        + ".",
        verdicts="two-sided Wilcoxon, Holm over 3 per cell; H2 holds unless contradicted",
        table="Primary outcome per learner (mean ± std; median [Q1, Q3])",
        metric=lambda c: prim[c.split("/")[0]],
        cell=cell,
        footer=f"Outcomes other than each env's primary one are secondary (no verdict). Ties: "
        f"|d| ≤ {TIE_TOL:g} on regret, exact equality otherwise. Bootstrap: {RESAMPLES} paired "
        f"resamples, seed {BOOTSTRAP_SEED}.",
    )


def _report(
    result: dict,
    seeds: list[int],
    meta: dict,
    *,
    title: str,
    key: str,
    primary: str,
    verdicts: str,
    table: str,
    metric: Callable[[str], str],
    cell: Callable[[dict], str],
    footer: str,
) -> list[str]:
    """One report's lines; ``key`` names a row ("condition" or "cell"), ``metric(row)`` its
    primary outcome and ``cell`` a learner's descriptives in the table."""
    from strol_gym.benchmarks.analysis.report import display

    git = meta.get("git") or {}
    desc = {(x[key], x["learner"], x["metric"]): x for x in result["descriptives"]}
    return [
        f"# {title}",
        "",
        f"Run seeds {seeds[0]}–{seeds[1]} per {key}; git {git.get('commit', '?')[:10]}"
        f"{' (dirty tree)' if git.get('dirty') else ''}; code fingerprint "
        f"{meta.get('extra', {}).get('code', '?')}.{primary}",
        "",
        f"## Verdicts ({verdicts})",
        "",
        *_verdict_lines(result),
        "",
        _sensitivity_line(result),
        "",
        f"## {table}",
        "",
        f"| {key} | " + " | ".join(display(lr) for lr in LEARNERS) + " |",
        "|---|" + "---|" * len(LEARNERS),
        *(
            f"| {row} | " + " | ".join(cell(desc[(row, lr, metric(row))]) for lr in LEARNERS) + " |"
            for row in result["verdicts"]
        ),
        "",
        "## Tests (StROL − baseline; lower is better)",
        "",
        f"| {key} {TESTS_HEAD}",
        "|---|---|---|---|---|---|---|---|---|",
        *_test_rows(result, key),
        "",
        footer,
    ]


def plot(result: dict, out: Path) -> list[Path]:
    """Probability that StROL's regret is lower than each baseline's, with bootstrap CIs, per
    condition (0.5 = no difference)."""
    from strol_gym.benchmarks.analysis.plots import learner_color, plt, save_figure
    from strol_gym.benchmarks.analysis.report import display

    out.mkdir(parents=True, exist_ok=True)
    conds = list(result["verdicts"])
    fig, ax = plt.subplots(figsize=(5.6, 3.2))
    width = 0.25
    for k, b in enumerate(BASELINES):
        xs, ys, lo, hi = [], [], [], []
        for i, cond in enumerate(conds):
            x = _primary_row(result, cond, b)
            xs.append(i + (k - 1) * width)
            ys.append(x["prob_improvement"])
            lo.append(x["prob_improvement"] - x["prob_improvement_ci95_low"])
            hi.append(x["prob_improvement_ci95_high"] - x["prob_improvement"])
        ax.errorbar(
            xs,
            ys,
            yerr=[lo, hi],
            fmt="o",
            capsize=3,
            color=learner_color(b),
            label=f"vs {display(b)}",
        )
    ax.axhline(0.5, color="k", lw=0.8, ls="--")
    ax.set_xticks(range(len(conds)), [f"{c}\n{result['verdicts'][c]}" for c in conds], fontsize=8)
    ax.set_ylabel(
        "P(StROL lower)" if isinstance(result["primary"], dict) else "P(StROL regret lower)"
    )
    ax.set_title("Confirmatory test: probability of improvement (95 % bootstrap CI)")
    ax.legend(fontsize=7)
    return save_figure(fig, out, "confirm")
