"""``strol-bench paper``: the paper's Fig. 4 comparison, its learners × four conditions."""

from __future__ import annotations

import argparse

from strol_gym.benchmarks.args import positive_int, run_options
from strol_gym.benchmarks.engine.conditions import PAPER_ENVS
from strol_gym.benchmarks.engine.config import MAX_RUNS, BenchConfig, paper_config
from strol_gym.benchmarks.experiments.run import RunsAndReports


class Paper(RunsAndReports):
    """Gradient, One, MOF, e2e (bounded and from scratch) and StROL under the paper's
    conditions, for one or both envs."""

    name = "paper"
    help = "the paper's Fig. 4 comparison: 6 learners x 4 conditions"
    description = (
        "The paper's comparison (Gradient, One, MOF, e2e, e2e-scratch, StROL under the "
        "training, clean, noisy-biased and uniform-prior conditions) for one or both envs. "
        "The Highway's human is the driver (the paper's MPC); --human replaces it in every "
        "condition, a labelled variant that states no H1/H2 verdict."
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
        p.add_argument(
            "--human",
            default=None,
            help="a registered human (e.g. nominal, the eq. M6 teacher) for every condition "
            "instead of the preset's; results go to results/paper-ENV-human-NAME",
        )
        run_options(p)

    def default_out(self, args: argparse.Namespace) -> str:
        out = super().default_out(args)
        return out if args.human is None else f"{out}-human-{args.human}"

    def plan(self, args: argparse.Namespace) -> BenchConfig:
        envs = list(PAPER_ENVS) if args.env == "all" else [args.env]
        if args.human is not None:
            from strol_gym.humans import HUMANS

            HUMANS.check_name(args.human)
        return paper_config(
            envs, runs=args.runs, seed=args.seed, block=args.block, human=args.human
        )
