"""Figures in the layout of the paper's Fig. 4, and learning curves. PNG and SVG, headless (Agg).

Grids: rows are envs, columns conditions, one column of points per learner: every run (a
jittered strip), the mean ± SEM (black bar) and the IQM with its 95 % bootstrap interval (white
diamond). A mark above a baseline (``stats.mark``: ↓ StROL significantly lower, ↑ higher, stars
the Holm p of the paired t-test) states StROL's test against it. Regret, almost binary per run,
is drawn on a symlog axis so the runs near 0 and the few beyond a regime switch both show.
Performance profiles: the fraction of runs with a score ≤ τ per learner. Curves: error
‖θ* − θ̂‖ after each correction step, mean ± SEM.
"""

from __future__ import annotations

import hashlib
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from strol_gym.benchmarks.analysis import robust, stats
from strol_gym.benchmarks.analysis.base import METRIC_LABELS, Analysis, display
from strol_gym.benchmarks.engine.conditions import env_preset
from strol_gym.files import write_figure
from strol_gym.lazy import LazyModule
from strol_gym.metrics import short


def _headless() -> None:
    import matplotlib

    matplotlib.use("Agg")


if TYPE_CHECKING:
    import matplotlib.pyplot as plt
else:  # matplotlib loads at the first figure: `strol-bench --help` does not need it
    plt = LazyModule("matplotlib.pyplot", before=_headless)

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
        write_figure(fig, p, dpi=130 if ext == "png" else None, bbox_inches="tight")
        paths.append(p)
    plt.close(fig)
    return paths


SYMLOG_METRICS = {"regret": 1e-3}
"""Metrics drawn on a symlog axis, with the linear range around 0: regret's runs sit near 0
and at 1–5, and a linear axis shows only the latter."""


def jitter(n: int, width: float = 0.55) -> np.ndarray:
    """Deterministic horizontal offsets for ``n`` points of a strip (a golden-ratio sequence:
    evenly spread, no random draw, the same figure every time)."""
    return ((np.arange(n) * 0.6180339887) % 1.0 - 0.5) * width


def run_strip(ax, y: np.ndarray, learners: list[str], cells: Sequence[dict | None]) -> None:
    """Every run of each learner (column of ``y``) as a jittered strip, with the mean ± SEM
    (black) and the IQM with its bootstrap interval (white diamond) beside it."""
    for i, learner in enumerate(learners):
        col = y[:, i] if y.size else np.array([])
        ax.scatter(
            i - 0.1 + jitter(len(col), 0.45),
            col,
            s=6,
            color=learner_color(learner),
            alpha=0.45,
            linewidths=0,
            zorder=2,
        )
        c = {k: np.nan if v is None else v for k, v in (cells[i] or {}).items()}
        if not np.isfinite(c.get("mean", np.nan)):
            continue
        ax.errorbar(i + 0.25, c["mean"], yerr=np.nan_to_num(c["sem"]), fmt="_", color="black",
                    markersize=10, capsize=2, lw=1.2, zorder=3)  # fmt: skip
        if np.isfinite(c.get("iqm", np.nan)):
            lo, hi = c["iqm"] - c["iqm_ci95_low"], c["iqm_ci95_high"] - c["iqm"]
            ax.errorbar(i + 0.25, c["iqm"], yerr=[[max(lo, 0)], [max(hi, 0)]], fmt="D",
                        mfc="white", mec="black", color="0.35", markersize=4, capsize=2,
                        lw=0.9, zorder=4)  # fmt: skip


def _save_with_legend(fig, axes, out: Path, stem: str) -> list[Path]:
    """One legend for the grid (the first panel's lines) below it, then ``save_figure``."""
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return save_figure(fig, out, stem)


def _env_grid(a: Analysis, metric_for_env: dict[str, str], width: float, height: float):
    """(envs with data for their metric, their conditions, columns, fig, axes): a grid with a
    row per env and a column per condition; no figure when no env has data."""
    envs = [e for e in metric_for_env if metric_for_env[e] in a.metrics_for(e)]
    if not envs:
        return envs, {}, 0, None, None
    conds = {e: [x.condition.name for x in a.config.experiments if x.env == e] for e in envs}
    ncol = max(len(c) for c in conds.values())
    fig, axes = plt.subplots(
        len(envs), ncol, figsize=(width * ncol + 0.6, height * len(envs)), squeeze=False
    )
    return envs, conds, ncol, fig, axes


def bar_grid(a: Analysis, metric_for_env: dict[str, str], out: Path, stem: str) -> list[Path]:
    """Fig. 4 layout: rows envs, columns conditions; per learner every run, the mean ± SEM and
    the IQM [95 % CI], with StROL's directional marks (``run_strip``)."""
    envs, conds, ncol, fig, axes = _env_grid(a, metric_for_env, 2.6, 2.8)
    if not envs:
        return []
    learners = list(a.config.learners)
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
            y = a.runs.get((env, cond, metric), np.empty((0, len(learners))))
            run_strip(ax, y, learners, cells)
            if metric in SYMLOG_METRICS:
                ax.set_yscale("symlog", linthresh=SYMLOG_METRICS[metric], linscale=0.5)
            for i, learner in enumerate(learners):
                t = a.test(env, cond, learner, metric)
                m = stats.mark(t)
                if m and t:
                    color = "black" if t["mean_diff"] < 0 else "#b00000"
                    ax.text(xs[i], 1.0, m, transform=ax.get_xaxis_transform(), ha="center",
                            va="bottom", fontsize=8, color=color)  # fmt: skip
            ax.set_xlim(-0.6, len(learners) - 0.4)
            ax.set_xticks(xs, [display(learner) for learner in learners], rotation=45, fontsize=8)
            ax.tick_params(axis="y", labelsize=8)
            ax.set_title(cond, fontsize=10, pad=13)
            if c == 0:
                ax.set_ylabel(f"{env_preset(env).env_id}\n{short(metric)}", fontsize=9)
    ref = display(a.config.reference)
    title = (
        "dots: every run; black bar: mean ± SEM; diamond: IQM [95 % bootstrap CI]. "
        f"↓ {ref} significantly lower than that learner, ↑ higher (paired t, Holm; "
        "* p<0.05, ** p<0.01, *** p<0.001)"
    )  # wrapped to the figure's width (~13 characters an inch at 9 pt), so one column reads
    fig.suptitle(textwrap.fill(title, int(13 * fig.get_figwidth())), fontsize=9)
    fig.tight_layout()
    return save_figure(fig, out, stem)


def profile_grid(a: Analysis, metric_for_env: dict[str, str], out: Path, stem: str) -> list[Path]:
    """Performance profiles: per env (rows) and condition (columns), the fraction of runs with
    a score ≤ τ for each learner (higher and further left is better); τ on a log axis for the
    symlog metrics (regret), from 0."""
    envs, conds, ncol, fig, axes = _env_grid(a, metric_for_env, 2.8, 2.5)
    if not envs:
        return []
    learners = list(a.config.learners)
    for r, env in enumerate(envs):
        metric = metric_for_env[env]
        log = metric in SYMLOG_METRICS
        for c in range(ncol):
            ax = axes[r, c]
            if c >= len(conds[env]) or (env, conds[env][c], metric) not in a.runs:
                ax.axis("off")
                continue
            cond = conds[env][c]
            y = a.runs[(env, cond, metric)]
            if not y.size:
                ax.axis("off")
                continue
            taus = robust.profile_taus(y, log=log)
            prof = robust.performance_profile(y, taus)
            for j, learner in enumerate(learners):
                ax.step(taus, prof[j], where="post", color=learner_color(learner), lw=1.3,
                        label=display(learner))  # fmt: skip
            if log:
                ax.set_xscale("symlog", linthresh=SYMLOG_METRICS[metric], linscale=0.5)
                ax.set_xlim(left=0.0)  # runs ≤ 0 (a planner's rounding dust) count at τ = 0
            ax.set_ylim(0, 1.02)
            ax.set_title(cond, fontsize=10)
            ax.set_xlabel(f"τ ({short(metric)})", fontsize=8)
            ax.tick_params(labelsize=8)
            if c == 0:
                ax.set_ylabel(f"{env_preset(env).env_id}\nfraction of runs ≤ τ", fontsize=9)
    return _save_with_legend(fig, axes, out, stem)


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
    return _save_with_legend(fig, axes, out, stem)


def make_plots(a: Analysis, out: Path) -> list[Path]:
    """Fig. 4 (each env's primary metric), one bar grid per metric, learning curves."""
    out.mkdir(parents=True, exist_ok=True)
    envs = list(dict.fromkeys(e.env for e in a.config.experiments))
    primary = {e: env_preset(e).primary_metric for e in envs}
    paths = bar_grid(a, primary, out, "fig4")
    shown = {e: m for e, m in primary.items() if m in a.metrics_for(e)}
    for metric in METRIC_LABELS:
        grid = {e: metric for e in envs if metric in a.metrics_for(e)}
        if grid != shown:  # the same grid as fig4 is fig4: one figure, not two copies
            paths += bar_grid(a, grid, out, f"bars_{metric}")
    paths += curve_grid(a, out)
    paths += profile_grid(a, {e: env_preset(e).primary_metric for e in envs}, out, "profiles")
    return paths
