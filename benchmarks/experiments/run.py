"""``strol-bench run``: learners on one env under paper conditions or one explicit condition."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from strol_gym.benchmarks.args import (
    RUN_CAPS,
    beta,
    check_learner_names,
    check_size_caps,
    fraction,
    json_object,
    learner_kwargs,
    learner_list,
    positive_int,
    run_options,
)
from strol_gym.benchmarks.engine.conditions import (
    CONDITION_NAMES,
    PAPER_ENVS,
    PAPER_LEARNERS,
    PRIORS,
    REFERENCE_LEARNER,
    custom_condition,
    env_preset,
    make_condition,
)
from strol_gym.benchmarks.engine.config import MAX_RUNS, BenchConfig, Experiment
from strol_gym.benchmarks.experiments.base import BenchExperiment, Outcome


class RunsAndReports(BenchExperiment):
    """An experiment that runs one config and writes the standard reports with their figures
    (summary.md, summary.csv, stats.csv, plots/): ``paper`` and ``run``."""

    def execute(self, config: BenchConfig, args: argparse.Namespace, out: Path) -> Outcome:
        from strol_gym.benchmarks.analysis.report import console_summary, write_reports
        from strol_gym.benchmarks.engine.runner import default_jobs

        jobs = args.jobs or default_jobs()
        t0 = time.perf_counter()
        rd, _, _ = self.run(config, out, args, reports=False)
        wall = time.perf_counter() - t0
        analysis, plots = write_reports(rd, plots=not args.no_plots)
        line = (
            f"\nwall time {wall:.1f} s (jobs={jobs}, backend={args.backend}); results in {rd.path}/"
        )
        notes = [f"summary: {rd.path / 'summary.md'}"]
        notes += [f"plot: {p}" for p in plots if p.suffix == ".png"]
        return Outcome(rd.path, [console_summary(analysis)], wall_line=line, notes=notes)


class Run(RunsAndReports):
    """One configuration: env, learners, paper conditions or an explicit one."""

    name = "run"
    help = "one configuration: env, learners, a condition or explicit noise/bias/prior/human"
    description = (
        "Run learners on one env under paper conditions (--condition, repeatable) "
        "or one explicit condition (--sigma/--bias/--prior/--human/--beta)."
    )

    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--env", required=True, help=f"{', '.join(PAPER_ENVS)} or a registered env preset"
        )
        p.add_argument(
            "--learners",
            type=learner_list,
            default=list(PAPER_LEARNERS),
            help="comma-separated registered names or module:attr (default: the paper's five)",
        )
        p.add_argument(
            "--reference", default=None, help="learner compared with the others (default strol)"
        )
        p.add_argument(
            "--condition",
            action="append",
            help="a registered condition (the paper's: " + ", ".join(CONDITION_NAMES) + ") or "
            "module:attr (repeatable); default training",
        )
        p.add_argument("--sigma", type=fraction("--sigma"), help="noise σ, fraction of a_max")
        p.add_argument("--bias", type=fraction("--bias", allow_negative=True), help="bias ε")
        p.add_argument("--prior", choices=PRIORS.names(), help="where θ* comes from")
        p.add_argument("--human", help="simulated human: a registered name or module:attr")
        p.add_argument("--beta", type=beta, help="rationality β (if the human takes it)")
        p.add_argument(
            "--human-kwargs",
            type=json_object("--human-kwargs"),
            help="JSON: the human's own kwargs",
        )
        p.add_argument(
            "--task", default=None, help="a Task name or module:attr (default: the env's)"
        )
        p.add_argument("--name", default="custom", help="name of the explicit condition")
        p.add_argument(
            "--runs",
            type=positive_int("--runs", MAX_RUNS),
            default=None,
            help=f"at most {MAX_RUNS}",
        )
        p.add_argument(
            "--corrections",
            type=positive_int("--corrections"),
            default=None,
            help="steps/episode",
        )
        p.add_argument(
            "--learner-kwargs",
            default=None,
            help='JSON: constructor kwargs per learner, e.g. \'{"strol": {"lam": 0.5}}\'',
        )
        run_options(p)

    def plan(self, args: argparse.Namespace) -> BenchConfig:
        check_size_caps(args, RUN_CAPS)
        check_learner_names(args.learners)
        return config_for_run(args)

    def default_out(self, args: argparse.Namespace) -> str:
        names = "-".join(dict.fromkeys(args.condition or ["training"]))
        if any(getattr(args, k) is not None for k in EXPLICIT):
            names = args.name
        return f"results/run-{args.env}-{names}"


EXPLICIT = ("sigma", "bias", "prior", "human", "beta", "human_kwargs")
"""The options that make one explicit condition instead of registered ones."""


def config_for_run(args: argparse.Namespace) -> BenchConfig:
    """The ``run`` command's config; ValueError naming the option that is wrong."""
    given = {k: getattr(args, k) for k in EXPLICIT if getattr(args, k) is not None}
    if given and args.condition:
        flags = ", ".join("--" + k.replace("_", "-") for k in given)
        raise ValueError(f"--condition cannot be combined with explicit {flags}")
    if given:
        if args.name in CONDITION_NAMES:
            raise ValueError(f"--name must not be a paper condition name ({args.name!r})")
        conds = [custom_condition(args.env, name=args.name, **given)]
    else:
        conds = [make_condition(args.env, c) for c in dict.fromkeys(args.condition or ["training"])]
    runs = args.runs or env_preset(args.env).runs
    exps = tuple(
        Experiment(
            args.env, c, runs=runs, seed=args.seed, n_corrections=args.corrections, task=args.task
        )
        for c in conds
    )
    kwargs = learner_kwargs(args.learner_kwargs, args.learners)
    learners = list(dict.fromkeys(args.learners))
    reference = args.reference or (
        REFERENCE_LEARNER if REFERENCE_LEARNER in learners else learners[0]
    )
    return BenchConfig(exps, tuple(learners), reference, args.block, kwargs)
