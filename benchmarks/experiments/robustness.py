"""``strol-bench robustness``: every learner against every correction model.

One condition per human model × noise level σ (bias 0, the designer's bimodal prior), all on
the same run seeds, so every cell is paired with every other on θ*, the start and the
candidates drawn; within a cell the learners are paired as in every run (the one runner). The
humans are the registered models (``strol_gym.humans.HUMANS``: the eq. M6 teacher, Boltzmann,
the driver, the changing preference and the zoo of ``strol_gym.humans.zoo``), each with its
default parameters except where the episode's length matters: the early person corrects for
the first 40 % of the corrections, the late one for the last 40 %, and the changing one
switches as ``strol-bench changing`` does.

The table and the heat map show the env's primary metric (Robot: regret; Highway: error),
mean per learner × human; a mark says whether StROL differs from that learner in that cell
(paired t-test, Holm over the baselines within the cell, as every run's stats.csv does).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from strol_gym.benchmarks.analysis.report import CELL_KEYS, IQM_KEYS, POI_KEYS, fmt
from strol_gym.benchmarks.args import (
    check_learner_names,
    float_list,
    learner_list,
    positive_int,
    run_options,
)
from strol_gym.benchmarks.engine.conditions import (
    PAPER_ENVS,
    PAPER_LEARNERS,
    REFERENCE_LEARNER,
    Condition,
    env_preset,
)
from strol_gym.benchmarks.engine.config import DEFAULT_BLOCK, MAX_RUNS, BenchConfig, Experiment
from strol_gym.benchmarks.experiments.base import BenchExperiment, Outcome, primary_metric
from strol_gym.benchmarks.experiments.changing import DEFAULT_SWITCH
from strol_gym.metrics import short

DEFAULT_RUNS = {"robot": 50, "highway": 100}
"""Runs per human × σ cell: the Robot's default fits 5 min on 2 cores (docs/results.md)."""
HIGH_SIGMA = 0.5
"""The second noise level: the paper's noisy-biased σ (without its bias)."""
COLUMNS = (
    "env",
    "human",
    "sigma",
    "learner",
    "metric",
    *CELL_KEYS,
    "mean_diff_vs_strol",
    "p_t_holm",
    "p_wilcoxon_holm",
    "mark",
    *IQM_KEYS,
    *POI_KEYS,
)
WORSE, BETTER = "↓", "↑"
"""Marks in a baseline's cell (``stats.LOWER`` / ``HIGHER``): StROL is significantly lower
(the baseline worse) / higher."""


def default_humans() -> list[str]:
    """Every built-in human model, in the registry's order."""
    from strol_gym.humans import HUMAN_MODELS

    return list(HUMAN_MODELS)


def default_sigmas(env: str) -> list[float]:
    """The env's training noise (if its person takes σ) and ``HIGH_SIGMA``."""
    training = env_preset(env).training_sigma
    return list(dict.fromkeys([*([] if training is None else [training]), HIGH_SIGMA]))


def human_kwargs(env: str, human: str) -> dict[str, Any] | None:
    """The parameters a human gets in this experiment: the timing models' windows and the
    changing preference's switch scale with the episode's corrections; others, defaults."""
    n = env_preset(env).n_corrections
    window = max(1, round(0.4 * n))
    if human == "early":
        return {"until": window}
    if human == "late":
        return {"start": n - window}
    if human == "changing":
        return {"switch_after": DEFAULT_SWITCH.get(env, n // 2)}
    return None


def cell_name(human: str, sigma: float) -> str:
    """A condition's name: the human and σ."""
    return f"{human}@{sigma:g}"


def make_config(
    env: str,
    *,
    humans: list[str] | None = None,
    sigmas: list[float] | None = None,
    learners: list[str] | None = None,
    runs: int | None = None,
    seed: int = 0,
    block: int = DEFAULT_BLOCK,
) -> BenchConfig:
    """Learners × humans × σ on ``env`` (ValueError naming a bad human or learner)."""
    from strol_gym.humans import HUMANS

    humans = list(dict.fromkeys(humans or default_humans()))
    for h in humans:
        HUMANS.check_name(h)
    learners = list(dict.fromkeys(learners or PAPER_LEARNERS))
    check_learner_names(learners)
    if REFERENCE_LEARNER not in learners:
        raise ValueError(f"--learners must include {REFERENCE_LEARNER!r}, the reference")
    n = runs or DEFAULT_RUNS.get(env, env_preset(env).runs)
    exps = tuple(
        Experiment(
            env,
            Condition(
                cell_name(h, s), sigma=s, bias=0.0, human=h, human_kwargs=human_kwargs(env, h)
            ),
            runs=n,
            seed=seed,
        )
        for s in dict.fromkeys(sigmas or default_sigmas(env))
        for h in humans
    )
    return BenchConfig(exps, tuple(learners), REFERENCE_LEARNER, block)


class Robustness(BenchExperiment):
    """Learners × correction models as an experiment: a table, a heat map, the tests."""

    name = "robustness"
    help = "every learner against every correction model (the human zoo) at one or two σ"
    description = (
        "Every learner against every registered correction model (nominal, Boltzmann, driver, "
        "changing and the zoo: feature-noise, myopic, skipping, over, under, early, late, "
        "mistaken) at the training σ and σ = 0.5; paired runs; a heat map of the primary "
        "metric with StROL's paired tests (Holm) marked."
    )
    columns = COLUMNS

    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        p.add_argument("--env", choices=PAPER_ENVS, default="robot")
        p.add_argument(
            "--humans",
            type=learner_list,
            default=None,
            help="comma-separated human models (default: every registered built-in)",
        )
        p.add_argument(
            "--sigmas",
            type=float_list("--sigmas", low=0.0),
            default=None,
            help=f"comma-separated noise levels σ (default: the env's training σ and {HIGH_SIGMA})",
        )
        p.add_argument(
            "--learners",
            type=learner_list,
            default=None,
            help="comma-separated learners, StROL among them (default: the paper's five)",
        )
        p.add_argument(
            "--runs",
            type=positive_int("--runs", MAX_RUNS),
            default=None,
            help=f"runs per human × σ (default: {DEFAULT_RUNS})",
        )
        run_options(p)

    def plan(self, args: argparse.Namespace) -> BenchConfig:
        from strol_gym.humans import check_fraction

        for s in args.sigmas or []:
            check_fraction("--sigmas", s)
        return make_config(
            args.env,
            humans=args.humans,
            sigmas=args.sigmas,
            learners=args.learners,
            runs=args.runs,
            seed=args.seed,
            block=args.block,
        )

    def execute(self, config: BenchConfig, args: argparse.Namespace, out: Path) -> Outcome:
        rd, a, wall = self.run(config, out, args)
        env = args.env
        metric = primary_metric(a, env)
        rows = collect_rows(a, config, env, metric)
        md = table_markdown(rows, config, metric)
        exp = config.experiments[0]
        meta = {
            "config": config.to_dict(),
            "metric": metric,
            "humans": list(dict.fromkeys(e.condition.human for e in config.experiments)),
            "sigmas": list(dict.fromkeys(e.condition.sigma for e in config.experiments)),
            "seeds": [exp.seeds.start, exp.seeds.stop - 1],
            "wall_time_s": wall,
        }
        return Outcome(rd.path, md, rows, meta, self.wall(wall, rd.path), state=metric)

    def plot(self, outcome: Outcome, folder: Path) -> list[Path]:
        return heat_map(outcome.rows, outcome.state, folder / "robustness")


def mark(test: dict[str, Any] | None) -> str:
    """``stats.mark``: ↓ / ↑ with stars when StROL's paired t-test (Holm) against this learner
    is significant: ↓ StROL lower (the learner worse), ↑ higher; '' otherwise."""
    from strol_gym.benchmarks.analysis.stats import mark as stats_mark

    return stats_mark(test)


def collect_rows(a: Any, config: BenchConfig, env: str, metric: str) -> list[dict[str, Any]]:
    """One row per human × σ × learner: the metric's descriptives and StROL's tests."""
    rows = []
    for exp in config.experiments:
        cond = exp.condition
        for learner in config.learners:
            c = a.cell(env, cond.name, learner, metric) or {}
            t = None if learner == config.reference else a.test(env, cond.name, learner, metric)
            rows.append(
                {
                    "env": env,
                    "human": cond.human,
                    "sigma": cond.sigma,
                    "learner": learner,
                    "metric": metric,
                    **{k: c.get(k) for k in CELL_KEYS},
                    # the test's difference is StROL minus the learner
                    "mean_diff_vs_strol": None if t is None else t.get("mean_diff"),
                    "p_t_holm": None if t is None else t.get("p_holm"),
                    "p_wilcoxon_holm": None if t is None else t.get("wilcoxon_p_holm"),
                    "mark": mark(t),
                    **{k: c.get(k) for k in IQM_KEYS},
                    **{k: None if t is None else t.get(k) for k in POI_KEYS},
                }
            )
    return rows


def _grid(rows: list[dict], sigma: float) -> tuple[list[str], list[str], dict]:
    """(learners, humans, {(learner, human): row}) of one σ, in the config's order."""
    mine = [r for r in rows if r["sigma"] == sigma]
    learners = list(dict.fromkeys(r["learner"] for r in mine))
    humans = list(dict.fromkeys(r["human"] for r in mine))
    return learners, humans, {(r["learner"], r["human"]): r for r in mine}


def table_markdown(rows: list[dict], config: BenchConfig, metric: str) -> list[str]:
    """Per σ: learners as rows, humans as columns, the mean with StROL's marks."""
    from strol_gym.benchmarks.analysis.report import display

    exp = config.experiments[0]
    lines = [
        f"Robustness to the correction model ({exp.env}, {exp.runs} runs per cell, seeds "
        f"{exp.seeds.start}–{exp.seeds.stop - 1}): mean {metric} per learner × human; "
        f"{WORSE} = StROL significantly lower than that learner, {BETTER} = higher (paired t, "
        "Holm over the baselines within the cell; * p < 0.05, ** < 0.01, *** < 0.001); "
        "bold = the lowest mean in the column.",
    ]
    for sigma in dict.fromkeys(r["sigma"] for r in rows):
        learners, humans, cell = _grid(rows, sigma)
        lines += ["", f"σ = {sigma:g}:", ""]
        lines.append("| learner | " + " | ".join(humans) + " |")
        lines.append("|---" * (len(humans) + 1) + "|")
        best = {h: _best(cell, learners, h) for h in humans}
        for learner in learners:
            cells = []
            for h in humans:
                r = cell[(learner, h)]
                v = fmt(_float(r["mean"]))
                v = f"**{v}**" if learner == best[h] else v
                cells.append(f"{v} {r['mark']}".strip())
            lines.append(f"| {display(learner)} | " + " | ".join(cells) + " |")
        wins = {
            learner: (
                sum(cell[(learner, h)]["mark"].startswith(WORSE) for h in humans),
                sum(cell[(learner, h)]["mark"].startswith(BETTER) for h in humans),
            )
            for learner in learners
            if learner != config.reference
        }
        lines += [
            "",
            f"StROL against each learner over the {len(humans)} humans at σ = {sigma:g} "
            "(significantly lower / higher): "
            + "; ".join(f"{display(learner)} {w}/{b}" for learner, (w, b) in wins.items())
            + ".",
            "",
            f"P(StROL better than that learner in a run) at σ = {sigma:g} (paired runs, ties ½; "
            "95 % bootstrap intervals in robustness.csv):",
            "",
            "| learner | " + " | ".join(humans) + " |",
            "|---" * (len(humans) + 1) + "|",
        ]
        for learner in learners:
            if learner != config.reference:
                poi = [fmt(_float(cell[(learner, h)]["prob_improvement"]), 2) for h in humans]
                lines.append(f"| {display(learner)} | " + " | ".join(poi) + " |")
    return lines


def _float(v: Any) -> float:
    return math.nan if v is None else float(v)


def _best(cell: dict, learners: list[str], human: str) -> str | None:
    means = [(_float(cell[(learner, human)]["mean"]), learner) for learner in learners]
    means = [(m, learner) for m, learner in means if math.isfinite(m)]
    return min(means)[1] if means else None


def heat_map(rows: list[dict], metric: str, stem: Path) -> list[Path]:
    """Learners × humans per σ: colour = the mean scaled within its column (0 = the column's
    lowest, 1 = its highest), text = the mean and StROL's mark."""
    import numpy as np

    from strol_gym.benchmarks.analysis.plots import plt, save_figure
    from strol_gym.benchmarks.analysis.report import display

    sigmas = list(dict.fromkeys(r["sigma"] for r in rows))
    first = _grid(rows, sigmas[0])
    width = 0.9 * len(first[1]) + 1.6
    height = (0.45 * len(first[0]) + 1.0) * len(sigmas)
    stem.parent.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(len(sigmas), 1, figsize=(width, height), squeeze=False)
    for ax, sigma in zip(axes[:, 0], sigmas, strict=True):
        learners, humans, cell = _grid(rows, sigma)
        m = np.array([[_float(cell[(learner, h)]["mean"]) for h in humans] for learner in learners])
        lo, hi = np.nanmin(m, axis=0), np.nanmax(m, axis=0)
        span = np.where(hi > lo, hi - lo, 1.0)
        ax.imshow((m - lo) / span, cmap="RdYlGn_r", vmin=0, vmax=1, aspect="auto")
        for i, learner in enumerate(learners):
            for j, h in enumerate(humans):
                r = cell[(learner, h)]
                ax.text(
                    j, i, f"{fmt(m[i, j], 2)}\n{r['mark']}", ha="center", va="center", fontsize=6.5
                )
        ax.set_xticks(range(len(humans)), humans, rotation=40, ha="right", fontsize=7)
        ax.set_yticks(range(len(learners)), [display(learner) for learner in learners], fontsize=7)
        ax.set_title(
            f"{short(metric)} (mean), σ = {sigma:g}: {WORSE} StROL lower, {BETTER} higher (Holm)",
            fontsize=8,
        )
    fig.tight_layout()
    return save_figure(fig, stem.parent, stem.name)
