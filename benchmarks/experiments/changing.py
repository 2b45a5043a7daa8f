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

from strol_gym.benchmarks.analysis.paper_numbers import PAPER_CHANGING
from strol_gym.benchmarks.analysis.report import fmt
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
    "mean",
    "std",
    "sem",
    "median",
    "n",
    "error_mean",
    "cos_error_mean",
    "p_t_holm",
    "p_wilcoxon_holm",
    "paper_mean",
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
                    **{k: c.get(k) for k in ("mean", "std", "sem", "median", "n")},
                    "error_mean": err.get("mean"),
                    "cos_error_mean": cos.get("mean"),
                    "p_t_holm": t.get("p_holm"),
                    "p_wilcoxon_holm": t.get("wilcoxon_p_holm"),
                    "paper_mean": paper.get(learner),
                }
            )
        exp = config.experiments[0]
        k = exp.condition.human_kwargs["switch_after"]
        md = table_markdown(rows, metric, k, exp.corrections, exp.condition.sigma)
        meta = {
            "config": config.to_dict(),
            "sigma": exp.condition.sigma,
            "switch_after": k,
            "seeds": [exp.seeds.start, exp.seeds.stop - 1],
            "wall_time_s": wall,
        }
        return Outcome(rd.path, md, rows, meta, self.wall(wall, rd.path), state=metric)

    def plot(self, outcome: Outcome, folder: Path) -> list[Path]:
        return plot(outcome.rows, outcome.state, folder / "changing")


def table_markdown(rows: list[dict], metric: str, k: int, n: int, sigma: float) -> list[str]:
    from strol_gym.benchmarks.analysis.report import display

    lines = [
        f"Changing preferences: θ* for {k} corrections, then −θ* for {n - k}; σ = {sigma:g}; "
        f"scored against the final preference. {metric} (mean ± std, SEM, median); p: StROL vs "
        "that learner, Holm over the four baselines.",
        "",
        f"| learner | {metric} ours | SEM | median | paper | error | 1 − cos | p (t) | "
        "p (Wilcoxon) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        paper = fmt_paper(r["paper_mean"])
        lines.append(
            f"| {display(r['learner'])} | {fmt(r['mean'])} ± {fmt(r['std'])} | {fmt(r['sem'])} | "
            f"{fmt(r['median'])} | {paper} | {fmt(r['error_mean'])} | "
            f"{fmt(r['cos_error_mean'])} | {fmt(r['p_t_holm'])} | {fmt(r['p_wilcoxon_holm'])} |"
        )
    return lines


def plot(rows: list[dict], metric: str, stem: Path) -> list[Path]:
    """Bars: mean ± SEM per learner; the paper's values as black diamonds."""
    from strol_gym.benchmarks.analysis.plots import learner_color, save_figure
    from strol_gym.benchmarks.analysis.report import display

    fig, ax = small_figure(stem)
    xs = range(len(rows))
    ax.bar(
        xs,
        [r["mean"] for r in rows],
        yerr=[r["sem"] for r in rows],
        color=[learner_color(r["learner"]) for r in rows],
        capsize=3,
        label="ours (mean ± SEM)",
    )
    paper = [(i, r["paper_mean"]) for i, r in enumerate(rows) if r["paper_mean"] is not None]
    if paper:
        ax.scatter(*zip(*paper, strict=True), marker="D", color="k", zorder=3, label="paper")
    ax.set_xticks(list(xs), [display(r["learner"]) for r in rows])
    ax.set_ylabel(short(metric))
    ax.set_title("Changing preferences")
    ax.legend(fontsize=8)
    return save_figure(fig, stem.parent, stem.name)
