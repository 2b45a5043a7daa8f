"""``strol-bench lambda``: StROL's λ (G = g + λ·ĝ) under the designer's bimodal prior and the
uniform prior, by default λ ∈ {0, 0.1, 0.5, 1, 2, 5, 10}: the authors' published figure's
{0, 0.1, 1, 10} and the values their README also names (0.5 to 10).

Each λ is its own results folder (``OUT/lam-<λ>/``, resumable like ``paper``), holding the
training condition (bimodal prior) and the uniform-prior condition on the same run seeds. λ = 0
is exactly Gradient. The sweep's table, meta and plot sit in ``OUT``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from strol_gym.benchmarks.analysis.paper_numbers import PAPER_LAMBDA
from strol_gym.benchmarks.analysis.report import CELL_KEYS, IQM_KEYS, fmt, fmt_ci
from strol_gym.benchmarks.args import float_list, positive_int, run_options
from strol_gym.benchmarks.engine.conditions import env_preset, make_condition
from strol_gym.benchmarks.engine.config import DEFAULT_BLOCK, BenchConfig, Experiment
from strol_gym.benchmarks.experiments.base import (
    BenchExperiment,
    Outcome,
    fmt_paper,
    small_figure,
)
from strol_gym.metrics import short

DEFAULT_LAMBDAS = (0.0, 0.1, 0.5, 1.0, 2.0, 5.0, 10.0)
PRIOR_CONDITIONS = {"bimodal": "training", "uniform": "uniform-prior"}
"""The prior θ* is drawn from -> the paper condition that has it (σ = the training noise)."""
COLUMNS = (
    "env",
    "prior",
    "lam",
    "metric",
    *CELL_KEYS,
    "paper_mean",
    *IQM_KEYS,
)


def lam_key(lam: float) -> str:
    return f"{lam:g}"


def make_config(
    env: str, lam: float, *, runs: int | None = None, seed: int = 0, block: int = DEFAULT_BLOCK
) -> BenchConfig:
    """StROL alone at λ = ``lam``, in the training and the uniform-prior conditions."""
    preset = env_preset(env)
    exps = tuple(
        Experiment(env, make_condition(env, c), runs=runs or preset.runs, seed=seed)
        for c in PRIOR_CONDITIONS.values()
    )
    return BenchConfig(exps, ("strol",), "strol", block, {"strol": {"lam": float(lam)}})


class LambdaSweep(BenchExperiment):
    """StROL at several λ under the bimodal and the uniform prior

    StROL's λ sweep (G = g + λ·ĝ) under the designer's bimodal prior and the uniform prior;
    regret (Robot) against λ with SEM bars and the paper's values.
    """

    name = "lambda"
    columns = COLUMNS
    needs_own_out = True

    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        p.add_argument("--env", choices=("robot",), default="robot")
        p.add_argument(
            "--lambdas",
            type=float_list("--lambdas", low=0.0),
            default=list(DEFAULT_LAMBDAS),
            help="comma-separated λ >= 0 (default 0,0.1,0.5,1,2,5,10)",
        )
        p.add_argument("--runs", type=positive_int("--runs"), default=None)
        run_options(p)

    def plan(self, args: argparse.Namespace) -> dict[float, BenchConfig]:
        return {
            lam: make_config(args.env, lam, runs=args.runs, seed=args.seed, block=args.block)
            for lam in dict.fromkeys(args.lambdas)
        }

    def execute(
        self, configs: dict[float, BenchConfig], args: argparse.Namespace, out: Path
    ) -> Outcome:
        metric = env_preset(args.env).primary_metric
        rows, walls, runs = [], {}, {}
        for lam, config in configs.items():
            _, a, wall = self.run(config, out / f"lam-{lam_key(lam)}", args)
            walls[lam_key(lam)] = wall
            for prior, cond in PRIOR_CONDITIONS.items():
                c = a.cell(args.env, cond, "strol", metric) or {}
                y = a.runs.get((args.env, cond, metric))
                if y is not None:
                    runs[(prior, lam)] = y[:, list(config.learners).index("strol")]
                rows.append(
                    {
                        "env": args.env,
                        "prior": prior,
                        "lam": lam,
                        "metric": metric,
                        **{k: c.get(k) for k in CELL_KEYS},
                        "paper_mean": PAPER_LAMBDA.get(prior, {}).get(lam),
                        **{k: c.get(k) for k in IQM_KEYS},
                    }
                )
        first = next(iter(configs.values()))
        meta = {
            "lambdas": list(args.lambdas),
            "conditions": dict(PRIOR_CONDITIONS),
            "configs": {lam_key(k): c.to_dict() for k, c in configs.items()},
            "seeds": [first.experiments[0].seeds.start, first.experiments[0].seeds.stop - 1],
            "wall_time_s": walls,
        }
        md = table_markdown(rows, metric)
        wall_line = self.wall(sum(walls.values()), out)
        return Outcome(out, md, rows, meta, wall_line, state=(metric, runs))

    def plot(self, outcome: Outcome, folder: Path) -> list[Path]:
        metric, runs = outcome.state
        return plot(outcome.rows, metric, folder / "lambda", runs)


def table_markdown(rows: list[dict], metric: str) -> list[str]:
    lines = [
        f"StROL's {metric} against λ (G = g + λ·ĝ; λ = 0 is Gradient): mean ± std, SEM, median, "
        "IQM [95 % CI] (the mean of the middle 50 % of the runs, percentile bootstrap over run "
        "seeds); the paper's values are read off the authors' published figure (approximate; "
        "it has λ = 0, 0.1, 1, 10 only).",
        "",
        f"| prior | λ | {metric} ours | SEM | median | IQM [95 % CI] | paper |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        paper = fmt_paper(r["paper_mean"])
        iqm = fmt_ci(*(r[k] for k in IQM_KEYS))
        lines.append(
            f"| {r['prior']} | {r['lam']:g} | {fmt(r['mean'])} ± {fmt(r['std'])} | "
            f"{fmt(r['sem'])} | {fmt(r['median'])} | {iqm} | {paper} |"
        )
    return lines


def plot(
    rows: list[dict], metric: str, stem: Path, runs: dict[tuple[str, float], Any] | None = None
) -> list[Path]:
    """Regret against λ (symlog x and y): every run (dots), mean ± SEM (line) and IQM (dashed)
    per prior; the paper's values as hollow marks."""
    from strol_gym.benchmarks.analysis.plots import SYMLOG_METRICS, jitter, save_figure

    fig, ax = small_figure(stem)
    for i, prior in enumerate(PRIOR_CONDITIONS):
        rs = sorted((r for r in rows if r["prior"] == prior), key=lambda r: r["lam"])
        color = f"C{i}"
        for r in rs:
            y = (runs or {}).get((prior, r["lam"]))
            if y is not None and len(y):
                x = r["lam"] * (1 + 0.25 * jitter(len(y))) + 0.02 * jitter(len(y))
                ax.scatter(x, y, s=4, color=color, alpha=0.3, linewidths=0)
        iqm = [(r["lam"], r["iqm"]) for r in rs if r.get("iqm") is not None]
        if iqm:
            ax.plot(*zip(*iqm, strict=True), ls="--", color=color, lw=1, label=f"IQM, {prior}")
        ax.errorbar(
            [r["lam"] for r in rs],
            [r["mean"] for r in rs],
            yerr=[r["sem"] for r in rs],
            marker="o",
            capsize=3,
            color=color,
            label=f"ours, {prior} prior (mean ± SEM)",
        )
        paper = [(r["lam"], r["paper_mean"]) for r in rs if r["paper_mean"] is not None]
        if paper:
            ax.scatter(
                *zip(*paper, strict=True),
                marker="D",
                facecolors="none",
                edgecolors=color,
                zorder=3,
                label=f"paper, {prior} prior",
            )
    ax.set_xscale("symlog", linthresh=0.1)
    if metric in SYMLOG_METRICS:
        ax.set_yscale("symlog", linthresh=SYMLOG_METRICS[metric], linscale=0.5)
    ax.set_xlabel("λ")
    ax.set_ylabel(short(metric))
    ax.set_title("StROL: G = g + λ·ĝ")
    ax.legend(fontsize=7)
    return save_figure(fig, stem.parent, stem.name)
