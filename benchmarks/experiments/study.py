"""``strol-bench study``: the paper's user study (H3) with simulated users in ``StROL-Study-v2``
(the population fitted to the authors' twelve participants, ``--participant fitted``;
``--env-version v1``: v1 with its hand-set participant; ``v0``: the published results,
deprecated).

Tasks 1–3 × learners × N simulated users, paired: user seed s (θ̂0, the user's noise and
timing) is the same for every learner. The runs go through the paper preset's runner and results
folder (env presets ``study1..3`` in ``conditions.py``: the env drives its own robot, so the
runner's action is zero, the paper's robot); this module adds the study's metrics (correction
time and count, which the env reports), the H3 verdicts, the table beside the paper's numbers
and the Fig. 6-style plots.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.analysis.report import (
    Analysis,
    aggregate,
    analyse,
    display,
    iqm_table,
    poi_table,
    pooled_lines,
    pooled_tests,
    robust_legend,
)
from strol_gym.benchmarks.analysis.stats import mark_legend
from strol_gym.benchmarks.args import (
    check_learner_names,
    learner_list,
    nonneg_int,
    positive_int,
)
from strol_gym.benchmarks.engine.conditions import (
    PAPER_LEARNERS,
    REFERENCE_LEARNER,
    Condition,
    env_preset,
)
from strol_gym.benchmarks.engine.config import BenchConfig, Experiment
from strol_gym.benchmarks.engine.episodes import regret_inputs
from strol_gym.benchmarks.engine.record import RunRecord, value
from strol_gym.benchmarks.engine.results import ResultsDir, write_csv
from strol_gym.benchmarks.experiments.base import BenchExperiment, Outcome
from strol_gym.envs.study import metrics as study_authors
from strol_gym.envs.study.versions import LATEST, V0, V2, VERSIONS, version_of
from strol_gym.files import write_text_atomic

TASKS = (1, 2, 3)
DEFAULT_USERS = 20
"""Simulated users per Task; the default run (3 Tasks × 5 learners × 20) fits in 10 minutes on
2 cores (docs/results.md has the measured wall time)."""
SEED = 20_000
"""First user seed: the study's seeds are 20000–29999, apart from evaluation and training."""
BLOCK = 4
"""Users per unit of work: small, so 2+ processes share the 60 s episodes evenly."""
SIGMA = 0.25
"""The users' noise (fraction of a_max), as the study's ĝ were trained."""
METRICS = (
    "regret",
    "regret_authors",
    "error",
    "correction_time",
    "correction_time_authors",
    "corrections",
)
LABELS = {
    "regret": "Regret (ours, eq. S1)",
    "regret_authors": "Regret (authors' way)",
    "error": "Final error ‖θ* − θ̂‖",
    "correction_time": "Correction time (s; ours, > 15 N)",
    "correction_time_authors": "Correction time (s; authors' way)",
    "corrections": "Corrections",
}
H3_BASELINES = ("one", "mof")
H3_METRICS = ("regret", "correction_time")
POOLED_METRICS = ("regret", "regret_authors", "correction_time", "correction_time_authors")
PAPER = {
    "regret_authors": {"one": (4.904, 1.125), "mof": (2.42, 0.48), "strol": (1.03, 0.08)},
    "correction_time_authors": {
        "one": (2.50, 1.57),
        "mof": (2.22, 1.53),
        "strol": (1.382, 1.40),
    },
}
"""The authors' published study means ± spread (their repository's table, averaged over the
three Tasks and 12 participants; the spread is unlabelled there, the paper's figure shows SEM).
They were computed the authors' way (``study_authors``), so they sit beside those rows only;
our own metrics have no published counterpart."""
PAPER_POOLED = {
    "regret_authors": "F(1.332, 14.651) = 9.108, p < 0.05",
    "correction_time_authors": "F(2, 22) = 5.602, p < 0.05",
}
"""The paper's text: repeated-measures ANOVA over One, MOF, StROL, participants' values
averaged over the Tasks (12 participants)."""
USERS = Condition("simulated-users", sigma=SIGMA, bias=0.0, prior="bimodal")
"""The study's condition for a person with a hand's noise (v0's and v1's: σ = 0.25, ε = 0);
``study_condition`` gives each version's person its own."""


def parse_tasks(text: str) -> tuple[int, ...]:
    """``"1,3"`` -> (1, 3); ArgumentTypeError naming --task and its valid values."""
    parts = [t.strip() for t in str(text).split(",") if t.strip()]
    try:
        tasks = tuple(dict.fromkeys(int(t) for t in parts))
    except ValueError:
        tasks = ()
    if not tasks or any(t not in TASKS for t in tasks):
        raise argparse.ArgumentTypeError(
            f"--task must be a comma-separated list of Task numbers from 1,2,3, got {text!r}"
        )
    return tasks


ENV_VERSIONS = tuple(VERSIONS)
PARTICIPANTS = tuple(sorted({who for v in VERSIONS.values() for who in v.participants}))
"""``fitted``: the population fitted to the twelve people (v2 only, its default); ``observer``:
v1's hand-set participant (v1's default); ``oracle``: v0's regret-judging user."""
DEFAULT_VERSION = LATEST.name
V0_WARNING = (
    "warning: StROL-Study-v0 is deprecated (u_H carries the arm's own motion, the user is an "
    "oracle); it stays for the published results. The study's default is v2."
)


def study_env(task: int, version: str = DEFAULT_VERSION) -> str:
    """The env preset of a study Task on ``version`` (``conditions.py``)."""
    return f"study{task}-{version}" if VERSIONS[version].participants else f"study{task}"


def study_condition(version: str = DEFAULT_VERSION, participant: str | None = None) -> Condition:
    """The study's condition: the version's person (``participant``; None: its default, its
    first, v0's the oracle), with σ = ``SIGMA`` and ε = 0 where the person takes them (the
    fitted person takes none: its noise is fitted). ValueError naming ``--participant`` if the
    version lacks it."""
    from strol_gym.envs.study.persons import ORACLE

    people = VERSIONS[version].participants or (ORACLE,)
    who = participant or people[0]
    if who not in people:
        raise ValueError(f"--participant {who!r} does not exist on {VERSIONS[version].env_id}")
    if who == "fitted":
        return dataclasses.replace(USERS, sigma=None, bias=None)
    return dataclasses.replace(USERS, human=None if who == people[0] else who)


def study_config(
    tasks: Sequence[int] = TASKS,
    users: int = DEFAULT_USERS,
    seed: int = SEED,
    learners: Sequence[str] = PAPER_LEARNERS,
    version: str = DEFAULT_VERSION,
    participant: str | None = None,
    reference: str | None = None,
) -> BenchConfig:
    """The study's paired benchmark: one experiment per Task, ``users`` user seeds each.
    ``reference``: the learner H3 tests against One and MOF (default StROL)."""
    condition = study_condition(version, participant)
    exps = tuple(Experiment(study_env(t, version), condition, runs=users, seed=seed) for t in tasks)
    learners = tuple(dict.fromkeys(learners))
    if not learners:
        raise ValueError("--learners must name at least one learner")
    if reference is not None and reference not in learners:
        raise ValueError(
            f"--reference must be one of the learners run ({', '.join(learners)}), "
            f"got {reference!r}"
        )
    if reference is None:
        reference = REFERENCE_LEARNER if REFERENCE_LEARNER in learners else learners[0]
    return BenchConfig(exps, learners, reference, BLOCK)


def h3_learners(config: BenchConfig) -> tuple[str, ...]:
    """The learners H3 compares: One, MOF and the tested one (the config's reference)."""
    return (*H3_BASELINES, config.reference)


def h3_evaluable(config: BenchConfig) -> bool:
    """Whether H3 can be tested: the tested learner (StROL unless ``--reference``), One and
    MOF all ran."""
    return config.reference not in H3_BASELINES and all(
        name in config.learners for name in h3_learners(config)
    )


def _task_of(env: str) -> int:
    return int(env.removeprefix("study")[0])


def h3_verdicts(a: Analysis) -> list[dict[str, Any]]:
    """H3 per Task: StROL against One and MOF on regret and on correction time (Holm-corrected
    paired t-tests, the Wilcoxon test alongside). "supported" needs all four lower."""
    out = []
    for exp in a.config.experiments:
        env, cond = exp.env, exp.condition.name
        parts, ok = [], True
        for metric in H3_METRICS:
            for base in H3_BASELINES:
                t = a.test(env, cond, base, metric)
                if t is None:
                    ok = False
                    parts.append(f"{LABELS[metric]} vs {display(base)}: no data")
                    continue
                sig = t["significant"]
                word = "no significant difference"
                if sig:
                    who = display(a.config.reference)
                    word = f"{who} lower" if t["mean_diff"] < 0 else f"{who} higher"
                ok = ok and sig and t["mean_diff"] < 0
                parts.append(
                    f"{LABELS[metric]} vs {display(base)}: {word} (Δ = {t['mean_diff']:+.3f}, "
                    f"p_Holm = {t['p_holm']:.3g}, Wilcoxon p_Holm = {t['wilcoxon_p_holm']:.3g})"
                )
        out.append(
            {
                "task": _task_of(env),
                "verdict": "H3 supported" if ok else "H3 not supported",
                "details": parts,
            }
        )
    return out


def _cell(a: Analysis, env: str, learner: str, metric: str) -> dict[str, Any] | None:
    return a.cell(env, USERS.name, learner, metric)


def table_rows(a: Analysis, records: Sequence[RunRecord]) -> list[dict[str, Any]]:
    """One row per learner × metric: mean ± SEM per Task, over all Tasks, and the paper's."""
    envs = [e.env for e in a.config.experiments]
    rows = []
    for metric in METRICS:
        for learner in a.config.learners:
            row: dict[str, Any] = {"metric": metric, "learner": learner}
            for env in envs:
                c = _cell(a, env, learner, metric)
                row[f"task{_task_of(env)}_mean"] = c["mean"] if c else math.nan
                row[f"task{_task_of(env)}_sem"] = c["sem"] if c else math.nan
            v = np.array(
                [value(r, metric) for r in records if r["learner"] == learner and metric in r],
                dtype=float,
            )
            v = v[np.isfinite(v)]
            row["all_mean"] = float(v.mean()) if v.size else math.nan
            row["all_sem"] = float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else math.nan
            row["all_n"] = int(v.size)
            paper = PAPER.get(metric, {}).get(learner, (math.nan, math.nan))
            row["paper_mean"], row["paper_spread"] = paper
            rows.append(row)
    return rows


def _pm(m: float, s: float) -> str:
    if not math.isfinite(m):
        return "n/a"
    return f"{m:.3f}" if not math.isfinite(s) else f"{m:.3f} ± {s:.3f}"


def table_markdown(rows: Sequence[dict[str, Any]], tasks: Sequence[int]) -> list[str]:
    """Markdown: mean ± SEM per Task and over the Tasks, the paper's mean beside (authors'-way
    rows only: the published numbers were computed that way)."""
    head = ["metric", "learner", *[f"Task {t}" for t in tasks], "all Tasks", "paper"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [LABELS[r["metric"]], display(r["learner"])]
        cells += [_pm(r[f"task{t}_mean"], r[f"task{t}_sem"]) for t in tasks]
        cells.append(_pm(r["all_mean"], r["all_sem"]))
        p, sp = r["paper_mean"], r["paper_spread"]
        if math.isfinite(p):
            cells.append(f"{p:g} ± {sp:g}")
        elif r["metric"] in PAPER:
            cells.append("—")
        else:
            cells.append("no like-for-like number")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def make_plots(a: Analysis, records: Sequence[RunRecord], out: Path) -> list[Path]:
    """Fig. 6 style: regret and correction time per Task and learner (mean ± SEM bars, every
    simulated user as a dot, StROL's directional mark against that learner: ↓ StROL lower, ↑
    higher, Holm-corrected t-test), and regret against correction time per run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from strol_gym.benchmarks.analysis.plots import jitter, learner_color, save_figure
    from strol_gym.benchmarks.analysis.stats import mark

    out.mkdir(parents=True, exist_ok=True)
    envs = [e.env for e in a.config.experiments]
    learners = list(a.config.learners)
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.6))
    width = 0.8 / len(learners)
    for ax, metric in zip(axes[:2], H3_METRICS, strict=True):
        for j, learner in enumerate(learners):
            for i, env in enumerate(envs):
                c = _cell(a, env, learner, metric)
                if c is None:
                    continue
                x = i + (j - (len(learners) - 1) / 2) * width
                ax.bar(x, c["mean"], width, yerr=c["sem"], color=learner_color(learner), capsize=2,
                       label=display(learner) if i == 0 else None)  # fmt: skip
                y = a.runs.get((env, USERS.name, metric))
                if y is not None and len(y):
                    ax.scatter(x + jitter(len(y), 0.6 * width), y[:, j], s=5, color="black",
                               alpha=0.5, linewidths=0, zorder=3)  # fmt: skip
                m = mark(a.test(env, USERS.name, learner, metric))
                if m:
                    top = c["mean"] + (c["sem"] or 0)
                    if y is not None and len(y):
                        top = max(top, float(np.nanmax(y[:, j])))
                    ax.text(x, top, m, ha="center", va="bottom", fontsize=7)
        ax.set_xticks(range(len(envs)), [f"Task {_task_of(e)}" for e in envs])
        ax.set_ylabel(LABELS[metric])
    axes[0].legend(fontsize=7)
    ax = axes[2]
    for learner in learners:
        rs = [r for r in records if r["learner"] == learner]
        ax.scatter([r["correction_time"] for r in rs], [r["regret"] for r in rs], s=10,
                   color=learner_color(learner), alpha=0.6, label=display(learner))  # fmt: skip
    ax.set_xlabel(LABELS["correction_time"])
    ax.set_ylabel(LABELS["regret"])
    ax.set_title("per simulated user", fontsize=9)
    return save_figure(fig, out, "study")


def robust_markdown(a: Analysis, envs: Sequence[str]) -> list[str]:
    """Per H3 metric: IQM [95 % CI] per Task and learner, and P(StROL better in a run) against
    each learner, per Task and over the Tasks (bootstrap stratified by Task)."""
    ref = display(a.config.reference)
    rows = [(f"Task {_task_of(e)}", e, USERS.name) for e in envs]
    out = [
        f"Heavy-tail statistics: {robust_legend(ref, a.resamples)} Marks beside IQMs: "
        f"{mark_legend(ref, 'wilcoxon')}.",
    ]
    for metric in H3_METRICS:
        if not any((e, USERS.name, metric) in a.runs for e in envs):
            continue
        agg = aggregate(a, [(e, USERS.name) for e in envs], metric, a.resamples)
        out += ["", f"IQM [95 % CI] of {LABELS[metric]}:", ""]
        out += iqm_table(a, envs[0], metric, rows, agg)
        poi = poi_table(a, envs[0], metric, rows, agg)
        if poi:
            out += ["", f"P({ref} better in a run) [95 % CI] on {LABELS[metric]}:", "", *poi]
    return out


def _anova_text(r: dict[str, Any]) -> str:
    """'F(df1, df2) = F, p_GG = p', or, when F is undefined, ``AnovaResult.line``'s reason
    (never "F = inf, p = 0")."""
    from strol_gym.benchmarks.analysis.stats import AnovaResult

    if not math.isfinite(r["F"]):
        return AnovaResult.from_row(r).line()
    return f"F({r['df1_gg']:.2f}, {r['df2_gg']:.2f}) = {r['F']:.2f}, p_GG = {r['p_gg']:.3g}"


def write_study_reports(rd: ResultsDir, *, plots: bool = True) -> dict[str, Any]:
    """Tables (CSV + markdown), statistics, verdicts (study.json) and plots from ``rd``."""
    from strol_gym.benchmarks.analysis.report import ANOVA_COLUMNS, STATS_COLUMNS, SUMMARY_COLUMNS

    records = rd.read_records()
    if not records:
        raise ValueError(f"{rd.path} holds no finished runs yet")
    add_authors_regret(records)
    metrics = [m for m in METRICS if any(m in r for r in records)]
    a = analyse(rd.config, records, metrics)
    tasks = [_task_of(e.env) for e in rd.config.experiments]
    rows = table_rows(a, records)
    cols = ["metric", "learner"]
    cols += [f"task{t}_{s}" for t in tasks for s in ("mean", "sem")]
    cols += ["all_mean", "all_sem", "all_n", "paper_mean", "paper_spread"]
    write_csv(rd.path / "study_table.csv", rows, cols)
    write_csv(rd.path / "summary.csv", a.summary, SUMMARY_COLUMNS)
    write_csv(rd.path / "stats.csv", a.posthoc, STATS_COLUMNS)
    write_csv(rd.path / "anova.csv", a.anova, ANOVA_COLUMNS)
    h3 = h3_evaluable(rd.config)
    # the learner H3 tests: the reference, unless that is a baseline (no StROL run)
    tested = "StROL" if rd.config.reference in H3_BASELINES else display(rd.config.reference)
    verd = h3_verdicts(a) if h3 else []
    anova = [
        f"- Task {_task_of(r['env'])}, {LABELS[r['metric']]}: {_anova_text(r)}"
        for r in a.anova
        if r["metric"] in H3_METRICS
    ]
    md = [
        f"# User study (H3) with simulated users ({_who(rd.config)})",
        "",
        f"{len(records) // len(rd.config.learners)} paired runs (Tasks {tasks}, "
        f"{rd.config.experiments[0].runs} users each, seeds from {rd.config.experiments[0].seed})"
        "; mean ± SEM; the paper's means are averaged over its Tasks.",
        "",
        *table_markdown(rows, tasks),
        "",
        "Repeated-measures ANOVA (Greenhouse–Geisser):",
        "",
        *anova,
        "",
    ]
    if h3:
        md += [
            f"H3 verdicts ({tested} vs One and MOF; Holm-corrected paired t-tests, α = 0.05):",
            "",
        ]
    else:
        md.append(
            f"H3 was not evaluated: it compares {tested} with One and MOF, and the learners "
            f"run were {', '.join(rd.config.learners)}."
        )
    for v in verd:
        md.append(f"- **Task {v['task']}: {v['verdict']}**")
        md += [f"  - {d}" for d in v["details"]]
    envs = [e.env for e in rd.config.experiments]
    md += ["", *robust_markdown(a, envs)]
    pooled = [
        pooled_tests(records, envs, h3_learners(rd.config), m)
        for m in POOLED_METRICS
        if h3 and any(m in r for r in records)
    ]
    if pooled:
        runs = rd.config.experiments[0].runs
        md += ["", *pooled_markdown(pooled, len(envs), runs, tested)]
    write_text_atomic(rd.path / "study_table.md", "\n".join(md) + "\n")
    paths = make_plots(a, records, rd.path / "plots") if plots else []
    result = {
        "tasks": tasks,
        "h3_evaluated": h3,
        "verdicts": verd,
        "pooled": [_pooled_json(r) for r in pooled],
        "table": rows,
        "plots": [str(p) for p in paths],
    }
    write_text_atomic(rd.path / "study.json", json.dumps(result, indent=1, default=float) + "\n")
    result["markdown"] = "\n".join(md)
    return result


def _who(config: BenchConfig) -> str:
    """The env and the simulated person of a study config, in words."""
    exp = config.experiments[0]
    if exp.env_id == V0.env_id:
        return f"{exp.env_id}, v0's user and the training human"
    if exp.env.endswith("-oracle"):
        kind = "oracle"
    elif exp.env_id == V2.env_id and not exp.env.endswith("-observer"):
        kind = "the fitted population"
    else:
        kind = "v1's held-out participant"
    return f"{exp.env_id}, {kind}"


def add_authors_regret(records: list[RunRecord]) -> None:
    """Each record's regret the authors' way (``study_authors.regret``), batched per Task."""
    for env in dict.fromkeys(r["env"] for r in records):
        rs = [r for r in records if r["env"] == env]
        cols = regret_inputs(rs)
        # the env's own planner (v2's keeps to the reachable set), scored the authors' way
        task = version_of(env_preset(env).env_id).numbered[_task_of(env)]()
        for r, v in zip(rs, study_authors.regret(task, *cols), strict=True):
            r["regret_authors"] = float(v)


def pooled_markdown(
    pooled: Sequence[dict[str, Any]], n_tasks: int, users: int, tested: str = "StROL"
) -> list[str]:
    """The paper's H3 analysis: each user's values averaged over the Tasks, a repeated-measures
    ANOVA over One, MOF and the tested learner (``tested``, as tables spell it), then the pairs
    (Holm)."""
    md = [
        "## H3 pooled the paper's way",
        "",
        f"Each simulated user's value averaged over the {n_tasks} Tasks, then a "
        f"repeated-measures ANOVA over One, MOF and {tested} (Greenhouse–Geisser) and paired tests "
        "of every pair (Holm over the three pairs), as the paper analysed its 12 participants. "
        f"The per-Task verdicts above are the stricter test (each Task alone, {users} users, "
        "Holm over four baselines).",
        "",
    ]
    for r in pooled:
        means = ", ".join(f"{display(k)} {v:.3f}" for k, v in r["means"].items())
        paper = PAPER_POOLED.get(r["metric"])
        md.append(f"**{LABELS[r['metric']]}** (n = {r['n']} users; means {means})")
        if paper:
            md.append(f"(paper: {paper})")
        md += ["", *pooled_lines(r), ""]
    return md


def _pooled_json(r: dict[str, Any]) -> dict[str, Any]:
    import dataclasses

    return {**r, "anova": dataclasses.asdict(r["anova"])}


class Study(BenchExperiment):
    """The simulated user study as an experiment; it writes its own tables (study_table.*)."""

    name = "study"
    help = "the user study (H3) with simulated users: Tasks 1-3 of StROL-Study-v2"
    description = (
        "StROL-Study-v2's Tasks x Gradient, One, MOF, e2e, StROL x simulated users "
        "(paired; the population fitted to the twelve real people by default); regret, "
        "correction time, H3 verdicts, table beside the paper's, plots. --env-version v1: v1 "
        "with its hand-set participant; v0: the published results (deprecated)."
    )

    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        """The ``study`` subcommand's options (checked by argparse: bad ones exit 2 up front)."""
        p.add_argument("--task", type=parse_tasks, default=TASKS, help="Tasks, e.g. 1,3 (1,2,3)")
        p.add_argument(
            "--users",
            type=positive_int("--users", 10_000),
            default=DEFAULT_USERS,
            help=f"simulated users per Task (default {DEFAULT_USERS})",
        )
        p.add_argument(
            "--seed", type=nonneg_int("--seed"), default=SEED, help=f"first user seed ({SEED})"
        )
        p.add_argument(
            "--env-version",
            choices=ENV_VERSIONS,
            default=DEFAULT_VERSION,
            help="StROL-Study-v2 (default: the fitted population), v1 (its hand-set "
            "participant) or v0 (the published results; deprecated)",
        )
        p.add_argument(
            "--participant",
            choices=PARTICIPANTS,
            default=None,
            help="the simulated person: fitted (v2's default: drawn from the population fitted "
            "to the twelve real people), observer (v1's default; hand-set, judges what it sees) "
            "or oracle (v0's user: the training human, satisfied by the plan's regret)",
        )
        p.add_argument(
            "--learners",
            type=learner_list,
            default=list(PAPER_LEARNERS),
            help="comma-separated registered names or module:attr, a --plugin's too (default: "
            "the paper's five); H3 is evaluated only with one, mof and strol (or "
            "--reference) among them",
        )
        p.add_argument(
            "--reference",
            default=None,
            metavar="NAME",
            help="the learner H3 tests against One and MOF (default strol); one of --learners",
        )
        p.add_argument("--out", default=None, help="results folder (default results/study)")
        p.add_argument(
            "--jobs",
            type=positive_int("--jobs"),
            default=None,
            help="worker processes (default: every available CPU); results do not depend on it",
        )
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        p.add_argument(
            "--force", action="store_true", help="replace a results folder made with another config"
        )
        p.add_argument("--no-plots", action="store_true", help="skip the figures")

    def plan(self, args: argparse.Namespace) -> BenchConfig:
        import sys

        version = getattr(args, "env_version", DEFAULT_VERSION)
        who = getattr(args, "participant", None)
        if version == V0.name:
            print(V0_WARNING, file=sys.stderr)
        try:
            learners = getattr(args, "learners", None) or list(PAPER_LEARNERS)
            check_learner_names(learners)
            return study_config(
                args.task,
                args.users,
                args.seed,
                learners,
                version=version,
                participant=who,
                reference=getattr(args, "reference", None),
            )
        except ValueError as e:
            print(f"strol-bench study: error: {e}", file=sys.stderr)
            raise SystemExit(2) from None

    def execute(self, config: BenchConfig, args: argparse.Namespace, out: Path) -> Outcome:
        """Run (or resume) the study; its table, verdicts and plots."""
        from strol_gym.benchmarks.engine.runner import default_jobs

        jobs = args.jobs or default_jobs()
        rd, _, wall = self.run(config, out, args, reports=False)
        result = write_study_reports(rd, plots=not args.no_plots)
        line = f"\nwall time {wall:.1f} s (jobs={jobs}); results in {rd.path}/"
        notes = [f"plot: {p}" for p in result["plots"] if p.endswith(".png")]
        return Outcome(rd.path, [result["markdown"]], wall_line=line, notes=notes)

    def default_out(self, args: argparse.Namespace) -> str:
        return "results/study"
