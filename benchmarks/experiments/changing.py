"""``strol-bench changing``: the paper's changing-preference simulation.

The human (``human="changing"``, :class:`strol_gym.humans.ChangingHuman`) teaches θ* for its
first k corrections and −θ* after that; every run is scored against the final preference (the
envs report the human's current θ*). Defaults as the authors ran it: Robot 2 corrections then 3,
noise σ = 0.25 of a_max (their absolute 0.025 with a per-axis bound of 0.1, i.e. 25 %). The
Highway has 10 corrections; its default switch keeps the same proportion (4, then 6). The five
paper learners, paired runs, the one runner.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from strol_gym.benchmarks.analysis import stats
from strol_gym.benchmarks.analysis.paper_numbers import PAPER_CHANGING
from strol_gym.benchmarks.analysis.report import (
    CELL_KEYS,
    IQM_KEYS,
    POI_KEYS,
    fmt,
    fmt_ci,
    robust_legend,
)
from strol_gym.benchmarks.args import finite, nonneg_int, positive_int, run_options
from strol_gym.benchmarks.engine.conditions import PAPER_ENVS, PAPER_LEARNERS, Condition, env_preset
from strol_gym.benchmarks.engine.config import DEFAULT_BLOCK, BenchConfig, Experiment
from strol_gym.benchmarks.experiments.base import (
    BenchExperiment,
    Outcome,
    fmt_paper,
    primary_metric,
    small_figure,
)
from strol_gym.metrics import short

DEFAULT_SIGMA = 0.25
"""Noise σ as a fraction of a_max: the authors' absolute 0.025 over their a_max = 0.1."""
DEFAULT_SWITCH = {"robot": 2, "highway": 4}
COLUMNS = (
    "env",
    "learner",
    "metric",
    *CELL_KEYS,
    "error_mean",
    "cos_error_mean",
    "p_t_holm",
    "p_wilcoxon_holm",
    "paper_mean",
    *IQM_KEYS,
    *POI_KEYS,
    "mark",
)


def make_config(
    env: str,
    *,
    runs: int | None = None,
    seed: int = 0,
    switch_after: int | None = None,
    sigma: float = DEFAULT_SIGMA,
    block: int = DEFAULT_BLOCK,
) -> BenchConfig:
    preset = env_preset(env)
    k = DEFAULT_SWITCH.get(env, preset.n_corrections // 2) if switch_after is None else switch_after
    if k >= preset.n_corrections:
        raise ValueError(
            f"--switch-after must be below the {preset.n_corrections} corrections of {env}, got {k}"
        )
    cond = Condition(
        "changing", sigma=sigma, bias=0.0, human="changing", human_kwargs={"switch_after": k}
    )
    exp = Experiment(env, cond, runs=runs or preset.runs, seed=seed)
    return BenchConfig((exp,), PAPER_LEARNERS, "strol", block)


class Changing(BenchExperiment):
    """changing preferences: the human teaches θ* for k corrections, then −θ*

    The paper's changing-preference simulation with the five paper learners; scored against
    the final preference.
    """

    name = "changing"
    columns = COLUMNS

    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        p.add_argument("--env", choices=PAPER_ENVS, default="robot")
        p.add_argument("--runs", type=positive_int("--runs"), default=None)
        p.add_argument(
            "--switch-after",
            type=nonneg_int("--switch-after"),
            default=None,
            help="corrections toward θ* before the switch (default: robot 2, highway 4)",
        )
        p.add_argument(
            "--sigma",
            type=finite("--sigma", low=0.0),
            default=DEFAULT_SIGMA,
            help=f"noise σ, a fraction of a_max (default {DEFAULT_SIGMA})",
        )
        run_options(p)

    def plan(self, args: argparse.Namespace) -> BenchConfig:
        return make_config(
            args.env,
            runs=args.runs,
            seed=args.seed,
            switch_after=args.switch_after,
            sigma=args.sigma,
            block=args.block,
        )

    def execute(self, config: BenchConfig, args: argparse.Namespace, out: Path) -> Outcome:
        rd, a, wall = self.run(config, out, args)
        env = args.env
        metric = primary_metric(a, env)
        paper = PAPER_CHANGING.get(env, {})
        rows = []
        for learner in config.learners:
            c = a.cell(env, "changing", learner, metric) or {}
            t = a.test(env, "changing", learner, metric) or {}
            err = a.cell(env, "changing", learner, "error") or {}
            cos = a.cell(env, "changing", learner, "cos_error") or {}
            rows.append(
                {
                    "env": env,
                    "learner": learner,
                    "metric": metric,
                    **{k: c.get(k) for k in CELL_KEYS},
                    "error_mean": err.get("mean"),
                    "cos_error_mean": cos.get("mean"),
                    "p_t_holm": t.get("p_holm"),
                    "p_wilcoxon_holm": t.get("wilcoxon_p_holm"),
                    "paper_mean": paper.get(learner),
                    **{k: c.get(k) for k in IQM_KEYS},
                    **{k: t.get(k) for k in POI_KEYS},
                    "mark": stats.mark(t),
                }
            )
        exp = config.experiments[0]
        kwargs = exp.condition.human_kwargs
        assert kwargs is not None  # the changing human's condition always sets switch_after
        k = kwargs["switch_after"]
        sigma = exp.condition.sigma
        assert sigma is not None  # the changing experiment always sets σ
        md = table_markdown(rows, metric, k, exp.corrections, sigma)
        meta = {
            "config": config.to_dict(),
            "sigma": exp.condition.sigma,
            "switch_after": k,
            "seeds": [exp.seeds.start, exp.seeds.stop - 1],
            "wall_time_s": wall,
        }
        runs = a.runs.get((env, "changing", metric))
        state = (metric, runs)
        return Outcome(rd.path, md, rows, meta, self.wall(wall, rd.path), state=state)

    def plot(self, outcome: Outcome, folder: Path) -> list[Path]:
        metric, runs = outcome.state
        return plot(outcome.rows, metric, folder / "changing", runs)


def table_markdown(rows: list[dict], metric: str, k: int, n: int, sigma: float) -> list[str]:
    from strol_gym.benchmarks.analysis.report import display

    lines = [
        f"Changing preferences: θ* for {k} corrections, then −θ* for {n - k}; σ = {sigma:g}; "
        f"scored against the final preference. {metric} (mean ± std with marks, SEM, median, "
        "IQM [95 % CI]); p: StROL vs that learner, Holm over the four baselines; P(StROL "
        "better) [95 % CI]: in a run. Marks: " + stats.mark_legend("StROL") + ".",
        robust_legend("StROL", pooled=False),
        "",
        f"| learner | {metric} ours | SEM | median | IQM [95 % CI] | paper | error | 1 − cos | "
        "p (t) | p (Wilcoxon) | P(StROL better) [95 % CI] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        paper = fmt_paper(r["paper_mean"])
        iqm = fmt_ci(*(r[k] for k in IQM_KEYS))
        poi = fmt_ci(*(r[k] for k in POI_KEYS))
        lines.append(
            f"| {display(r['learner'])} | {fmt(r['mean'])} ± {fmt(r['std'])}{r['mark']} | "
            f"{fmt(r['sem'])} | {fmt(r['median'])} | {iqm} | {paper} | {fmt(r['error_mean'])} | "
            f"{fmt(r['cos_error_mean'])} | {fmt(r['p_t_holm'])} | {fmt(r['p_wilcoxon_holm'])} | "
            f"{poi} |"
        )
    return lines


def plot(rows: list[dict], metric: str, stem: Path, runs: np.ndarray | None = None) -> list[Path]:
    """Every run per learner (dots), the mean ± SEM (black) and IQM [95 % CI] (white diamond),
    StROL's directional marks; the paper's values as black diamonds."""
    from strol_gym.benchmarks.analysis.plots import SYMLOG_METRICS, run_strip, save_figure
    from strol_gym.benchmarks.analysis.report import display

    fig, ax = small_figure(stem)
    xs = range(len(rows))
    learners = [r["learner"] for r in rows]
    y = np.empty((0, len(rows))) if runs is None else runs
    run_strip(ax, y, learners, rows)
    if metric in SYMLOG_METRICS:
        ax.set_yscale("symlog", linthresh=SYMLOG_METRICS[metric], linscale=0.5)
    for i, r in enumerate(rows):
        if r["mark"]:
            ax.text(i, 1.0, r["mark"], transform=ax.get_xaxis_transform(), ha="center",
                    va="bottom", fontsize=8)  # fmt: skip
    paper = [(i, r["paper_mean"]) for i, r in enumerate(rows) if r["paper_mean"] is not None]
    if paper:
        ax.scatter(*zip(*paper, strict=True), marker="D", color="k", s=14, zorder=5,
                   label="paper (mean)")  # fmt: skip
    ax.set_xticks(list(xs), [display(r["learner"]) for r in rows])
    ax.set_ylabel(short(metric))
    ax.set_title("Changing preferences: runs, mean ± SEM, IQM [95 % CI]", fontsize=9, pad=12)
    ax.legend(fontsize=8)
    return save_figure(fig, stem.parent, stem.name)
