"""``strol-bench basin``: Fig. 2-style basin-of-attraction maps for g (Gradient) and g + ĝ
(StROL), from :func:`strol_gym.analysis.basin_map`.

A cell is θ̂0 on a grid over a 2-D slice of the parameter space; its colour is the final error
after ``--steps`` corrections by one fixed, seeded eq. M6 human (σ = ``--sigma``). A cell
*converges* when that error is at most 0.25·‖θ*‖ (``strol_gym.analysis.CONVERGED_TOL``).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from strol_gym.benchmarks.args import (
    BASIN_CAPS,
    add_allow_large,
    check_size_caps,
    finite,
    float_list,
    nonneg_int,
    positive_int,
)
from strol_gym.benchmarks.engine.conditions import env_preset
from strol_gym.benchmarks.experiments.base import BenchExperiment, Outcome

LEARNERS = {"gradient": "g (Gradient)", "strol": "g + ĝ (StROL)"}
COLUMNS = ("learner", "theta0_a", "theta0_b", "error", "converged")
DEFAULT_SEED = 1000
"""In the diagnostics seed range: the human's draws, not an evaluation run."""


class Basin(BenchExperiment):
    """basin-of-attraction maps for g and g + ĝ (Fig. 2 style)

    Final error from every θ̂0 of a grid (a 2-D slice), for Gradient's g and StROL's g + ĝ,
    with one fixed seeded human; prints the fraction that converges.
    """

    name = "basin"
    columns = COLUMNS

    needs_own_out = True

    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        p.add_argument("--env", choices=("robot", "highway"), default="robot")
        p.add_argument(
            "--grid", type=positive_int("--grid", low=2), default=41, help="cells per axis (≥ 2)"
        )
        p.add_argument("--steps", type=positive_int("--steps"), default=10, help="corrections (10)")
        p.add_argument(
            "--sigma", type=finite("--sigma", low=0.0), default=0.25, help="noise σ (0.25)"
        )
        p.add_argument(
            "--seed", type=nonneg_int("--seed"), default=DEFAULT_SEED, help="the human's seed"
        )
        p.add_argument(
            "--theta-star",
            type=float_list("--theta-star", low=-math.inf),
            default=None,
            help="the human's θ*, comma-separated (default: the first prior mode)",
        )
        p.add_argument("--out", default=None, help="results folder (default results/basin-<env>)")
        p.add_argument("--no-plots", action="store_true")
        add_allow_large(p)

    def plan(self, args: argparse.Namespace) -> None:
        check_size_caps(args, BASIN_CAPS)

    def execute(self, plan: None, args: argparse.Namespace, out: Path) -> Outcome:
        import gymnasium as gym

        from strol_gym.analysis import CONVERGED_TOL, basin_map
        from strol_gym.wrappers.online_learning import learning_env

        env = gym.make(env_preset(args.env).env_id)
        task = learning_env(env).task
        env.close()
        t0 = time.perf_counter()
        maps = {
            learner: basin_map(
                task,
                learner,
                args.grid,
                theta_star=args.theta_star,
                steps=args.steps,
                sigma=args.sigma,
                seed=args.seed,
            )
            for learner in LEARNERS
        }
        wall = time.perf_counter() - t0
        rows = []
        for learner, m in maps.items():
            g0, g1 = np.meshgrid(m.axis0, m.axis1)
            for a, b, e, c in zip(
                g0.ravel(), g1.ravel(), m.error.ravel(), m.converged.ravel(), strict=True
            ):
                rows.append(
                    {
                        "learner": learner,
                        "theta0_a": a,
                        "theta0_b": b,
                        "error": e,
                        "converged": bool(c),
                    }
                )
        star = next(iter(maps.values())).theta_star
        md = [
            f"Basin of attraction, {env_preset(args.env).env_id}: θ* = "
            f"{np.round(star, 3).tolist()}, {args.grid}×{args.grid} grid of θ̂0, {args.steps} "
            f"corrections, σ = {args.sigma:g}, seed {args.seed}. Converges: final error ≤ "
            f"{CONVERGED_TOL:g}·‖θ*‖.",
            "",
            "| rule | fraction converged | median final error |",
            "|---|---|---|",
            *(
                f"| {LEARNERS[learner]} | {m.fraction_converged:.3f} | {np.median(m.error):.3f} |"
                for learner, m in maps.items()
            ),
        ]
        meta = {
            "env": args.env,
            "grid": args.grid,
            "steps": args.steps,
            "sigma": args.sigma,
            "seed": args.seed,
            "theta_star": star.tolist(),
            "dims": list(next(iter(maps.values())).dims),
            "converged_tol": CONVERGED_TOL,
            "fraction_converged": {learner: m.fraction_converged for learner, m in maps.items()},
            "wall_time_s": wall,
        }
        return Outcome(out, md, rows, meta, self.wall(wall, out), state=(maps, task))

    def plot(self, outcome: Outcome, folder: Path) -> list[Path]:
        maps, task = outcome.state
        return plot(maps, task, folder)


def plot(maps: dict, task, out: Path) -> list[Path]:
    """Side-by-side maps of the final error; the converged region outlined, θ* and the prior
    modes marked."""
    from strol_gym.benchmarks.analysis.plots import plt, save_figure

    out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(1, len(maps), figsize=(4.2 * len(maps), 3.6), squeeze=False)
    vmax = max(float(m.error.max()) for m in maps.values())
    names = task.feature_names
    for ax, (learner, m) in zip(axes[0], maps.items(), strict=True):
        ext = [m.axis0[0], m.axis0[-1], m.axis1[0], m.axis1[-1]]
        im = ax.imshow(m.error, origin="lower", extent=ext, vmin=0, vmax=vmax, cmap="viridis")
        if m.error.shape[0] > 1 and m.error.shape[1] > 1:
            ax.contour(m.axis0, m.axis1, m.converged.astype(float), levels=[0.5], colors="w")
        i, j = m.dims
        ax.plot(m.theta_star[i], m.theta_star[j], "r*", ms=12, label="θ*")
        modes = np.asarray(task.prior_modes)
        ax.plot(modes[:, i], modes[:, j], "wo", mfc="none", label="prior modes")
        ax.set_title(f"{LEARNERS[learner]}: {m.fraction_converged:.0%} converge")
        ax.set_xlabel(f"θ̂0[{names[i]}]")
        if ax is axes[0, 0]:
            ax.set_ylabel(f"θ̂0[{names[j]}]")
        ax.legend(fontsize=7, loc="lower left")
    fig.colorbar(im, ax=list(axes[0]), label="final error ‖θ̂ − θ*‖")
    return save_figure(fig, out, "basin")
