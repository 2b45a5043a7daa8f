"""Figures in the layout of the paper's Fig. 4, and learning curves. PNG and SVG, headless (Agg).

Bars: rows are envs, columns conditions, one bar per learner (mean with SEM error bars). A star
above a baseline's bar marks a significant paired difference between StROL and that baseline
(Holm-corrected t-test). Curves: error ‖θ* − θ̂‖ after each correction step, mean ± SEM.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from strol_gym.benchmarks.analysis import stats
from strol_gym.benchmarks.analysis.base import METRIC_LABELS, Analysis, display
from strol_gym.benchmarks.engine.conditions import env_preset

from strol_gym.metrics import short

PAPER_COLORS = {
    "gradient": "#7f7f7f",
    "one": "#1f77b4",
    "mof": "#2ca02c",
    "e2e": "#ff7f0e",
    "strol": "#d62728",
}
"""The paper's five learners keep the colours of its figures."""
PALETTE = ("#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf", "#393b79", "#637939", "#843c39")
"""Colours for every other learner (tab10's remaining hues, then darker ones)."""


def learner_color(name: str) -> str:
    """A learner's colour in every plot: the paper's for its five, else one from ``PALETTE``
    chosen by the name itself, so a learner keeps its colour whatever else is plotted."""
    if name in PAPER_COLORS:
        return PAPER_COLORS[name]
    return PALETTE[int(hashlib.sha256(name.encode()).hexdigest(), 16) % len(PALETTE)]


def save_figure(fig, out: Path, stem: str) -> list[Path]:
    """``out/stem.png`` (130 dpi) and ``out/stem.svg``, then close ``fig``: every plot's files."""
    paths = []
    for ext in ("png", "svg"):
        p = out / f"{stem}.{ext}"
        fig.savefig(p, dpi=130 if ext == "png" else None, bbox_inches="tight")
        paths.append(p)
    plt.close(fig)
    return paths


def bar_grid(a: Analysis, metric_for_env: dict[str, str], out: Path, stem: str) -> list[Path]:
    """Fig. 4 layout: rows envs, columns conditions, bars per learner with SEM and stars."""
    envs = [e for e in metric_for_env if metric_for_env[e] in a.metrics_for(e)]
    if not envs:
        return []
    conds = {e: [x.condition.name for x in a.config.experiments if x.env == e] for e in envs}
    ncol = max(len(c) for c in conds.values())
    learners = list(a.config.learners)
    fig, axes = plt.subplots(
        len(envs), ncol, figsize=(2.6 * ncol + 0.6, 2.8 * len(envs)), squeeze=False
    )
    xs = np.arange(len(learners))
    for r, env in enumerate(envs):
        metric = metric_for_env[env]
        for c in range(ncol):
            ax = axes[r, c]
            if c >= len(conds[env]):
                ax.axis("off")
                continue
            cond = conds[env][c]
            cells = [a.cell(env, cond, learner, metric) for learner in learners]
            mean = np.array([x["mean"] if x else np.nan for x in cells])
            sem = np.array([x["sem"] if x else np.nan for x in cells])
            ax.bar(
                xs,
                mean,
                yerr=np.nan_to_num(sem),
                color=[learner_color(learner) for learner in learners],
                capsize=3,
                edgecolor="black",
                linewidth=0.5,
            )
            top = np.nanmax(mean + np.nan_to_num(sem)) if np.isfinite(mean).any() else 1.0
            for i, learner in enumerate(learners):
                t = a.test(env, cond, learner, metric)
                s = stats.stars(t["p_holm"]) if t else ""
                if s:
                    y = mean[i] + np.nan_to_num(sem[i]) + 0.03 * abs(top)
                    color = "black" if t["mean_diff"] < 0 else "#b00000"
                    ax.text(xs[i], y, s, ha="center", va="bottom", fontsize=9, color=color)
            ax.set_ylim(
                min(0.0, np.nanmin(mean - np.nan_to_num(sem))), 1.15 * top if top > 0 else 1
            )
            ax.set_xticks(xs, [display(learner) for learner in learners], rotation=45, fontsize=8)
            ax.tick_params(axis="y", labelsize=8)
            ax.set_title(cond, fontsize=10)
            if c == 0:
                ax.set_ylabel(f"{env_preset(env).env_id}\n{short(metric)}", fontsize=9)
    ref = display(a.config.reference)
    fig.suptitle(
        f"mean ± SEM; * {ref} differs from that learner (paired t, Holm p<0.05): black = {ref} "
        f"lower, red = {ref} higher",
        fontsize=9,
    )
    fig.tight_layout()
    return save_figure(fig, out, stem)


def curve_grid(a: Analysis, out: Path, stem: str = "curves_error") -> list[Path]:
    """Error after each correction step (step 0 = θ̂0), mean ± SEM, rows envs, cols conditions."""
    envs = list(dict.fromkeys(e.env for e in a.config.experiments))
    conds = {e: [x.condition.name for x in a.config.experiments if x.env == e] for e in envs}
    ncol = max(len(c) for c in conds.values())
    fig, axes = plt.subplots(
        len(envs), ncol, figsize=(2.8 * ncol + 0.6, 2.5 * len(envs)), squeeze=False
    )
    for r, env in enumerate(envs):
        for c in range(ncol):
            ax = axes[r, c]
            if c >= len(conds[env]):
                ax.axis("off")
                continue
            cond = conds[env][c]
            for learner in a.config.learners:
                cur = a.curves.get((env, cond, learner))
                if cur is None:
                    continue
                steps = np.arange(len(cur["mean"]))
                col = learner_color(learner)
                ax.plot(steps, cur["mean"], color=col, label=display(learner), lw=1.5)
                lo, hi = cur["mean"] - cur["sem"], cur["mean"] + cur["sem"]
                ax.fill_between(steps, lo, hi, color=col, alpha=0.2, lw=0)
            ax.set_title(cond, fontsize=10)
            ax.set_xlabel("correction step", fontsize=8)
            ax.tick_params(labelsize=8)
            if c == 0:
                ax.set_ylabel(f"{env_preset(env).env_id}\n‖θ* − θ̂‖", fontsize=9)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return save_figure(fig, out, stem)


def make_plots(a: Analysis, out: Path) -> list[Path]:
    """Fig. 4 (each env's primary metric), one bar grid per metric, learning curves."""
    out.mkdir(parents=True, exist_ok=True)
    envs = list(dict.fromkeys(e.env for e in a.config.experiments))
    paths = bar_grid(a, {e: env_preset(e).primary_metric for e in envs}, out, "fig4")
    for metric in METRIC_LABELS:
        paths += bar_grid(a, dict.fromkeys(envs, metric), out, f"bars_{metric}")
    paths += curve_grid(a, out)
    return paths
