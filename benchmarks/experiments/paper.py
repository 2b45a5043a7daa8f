"""``strol-bench paper``: the paper's Fig. 4 comparison, five learners × four conditions."""

from __future__ import annotations

import argparse

from strol_gym.benchmarks.args import positive_int, run_options
from strol_gym.benchmarks.engine.conditions import PAPER_ENVS
from strol_gym.benchmarks.engine.config import MAX_RUNS, BenchConfig, paper_config
from strol_gym.benchmarks.experiments.run import RunsAndReports


class Paper(RunsAndReports):
    """Gradient, One, MOF, e2e and StROL under the paper's conditions, for one or both envs."""

    name = "paper"
    help = "the paper's Fig. 4 comparison: 5 learners x 4 conditions"
    description = (
        "The paper's comparison (Gradient, One, MOF, e2e, StROL under the training, "
        "clean, noisy-biased and uniform-prior conditions) for one or both envs."
    )

    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        p.add_argument("--env", choices=(*PAPER_ENVS, "all"), default="all")
        p.add_argument(
            "--runs",
            type=positive_int("--runs", MAX_RUNS),
            default=None,
            help="runs per condition (default: the paper's, Robot 100, Highway 250; at most "
            f"{MAX_RUNS})",
        )
        run_options(p)

    def plan(self, args: argparse.Namespace) -> BenchConfig:
        envs = list(PAPER_ENVS) if args.env == "all" else [args.env]
        return paper_config(envs, runs=args.runs, seed=args.seed, block=args.block)
