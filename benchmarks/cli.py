"""``strol-bench``: run the paper's comparison, one configuration, training, listings, reports.

Every argument is checked before any work starts: a bad one exits with status 2 and a message
naming the argument and its valid values (argparse's convention).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
import types
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from strol_gym.benchmarks.backends import add_backend_options, backend_kwargs
from strol_gym.benchmarks.conditions import (
    CONDITION_NAMES,
    ENV_PRESETS,
    PAPER_ENVS,
    PAPER_LEARNERS,
    PRIORS,
    REFERENCE_LEARNER,
    custom_condition,
    env_preset,
    make_condition,
)
from strol_gym.benchmarks.config import (
    DEFAULT_BLOCK,
    MAX_RUNS,
    BenchConfig,
    Experiment,
    paper_config,
)
from strol_gym.benchmarks.results import ResultsError

from strol_gym.learners.protocol import LearnerFailed
from strol_gym.limits import RUN_CAPS, add_allow_large, check_size_caps


# ---------------------------------------------------------------------- argument types
def _positive_int(name: str, high: int | None = None, *, low: int = 1):
    """An argparse type: an integer in [low, high] (low defaults to 1; no upper bound)."""
    rng = f">= {low}" if high is None else f"in [{low}, {high}]"

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{name} must be an integer {rng}, got {text!r}"
            ) from None
        if v < low or (high is not None and v > high):
            raise argparse.ArgumentTypeError(f"{name} must be an integer {rng}, got {v}")
        return v

    return parse


def _nonneg_int(name: str):
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{name} must be an integer >= 0, got {text!r}"
            ) from None
        if v < 0:
            raise argparse.ArgumentTypeError(f"{name} must be an integer >= 0, got {v}")
        return v

    return parse


def _fraction(name: str, allow_negative: bool = False):
    """σ or ε as a fraction of a_max, checked by the humans' own rule (one range everywhere)."""
    from strol_gym.humans import check_fraction

    def parse(text: str) -> float:
        try:
            return check_fraction(name, text, allow_negative=allow_negative)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    return parse


def _beta(text: str) -> float:
    from strol_gym.humans import check_beta

    try:
        return check_beta(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"--{e}") from None


def _learner_list(text: str) -> list[str]:
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise argparse.ArgumentTypeError("learners must name at least one learner")
    return names


def check_learner_names(names: Sequence[str]) -> None:
    """ValueError for a name that is neither registered nor an importable ``module:attr``."""
    from strol_gym.learners.registry import LEARNERS

    for name in names:
        LEARNERS.check_name(name)


def _plugin_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--plugin",
        action="append",
        default=[],
        metavar="MODULE",
        help="import a module (or a .py file) that registers your own learners, humans, Tasks "
        "or conditions (repeatable); see docs/extending.md",
    )


# ---------------------------------------------------------------------- parser
def _common_run_options(p: argparse.ArgumentParser) -> None:
    _plugin_option(p)
    p.add_argument("--out", default=None, help="results folder (default results/<preset>)")
    p.add_argument(
        "--jobs",
        type=_positive_int("--jobs"),
        default=None,
        help="worker processes (default: every available CPU); results do not depend on it",
    )
    p.add_argument("--seed", type=_nonneg_int("--seed"), default=0, help="first run seed (0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--force",
        action="store_true",
        help="delete an existing results folder made with another config and start over",
    )
    p.add_argument(
        "--block",
        type=_positive_int("--block"),
        default=DEFAULT_BLOCK,
        help=f"run seeds per unit of work, batched together (default {DEFAULT_BLOCK})",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    add_backend_options(p)


_COMMON = types.SimpleNamespace(
    positive_int=_positive_int, nonneg_int=_nonneg_int, run_options=_common_run_options
)
"""The option helpers the experiment presets' own parser blocks use."""


PRESETS = {"changing": "changing", "lambda": "lambda_sweep", "basin": "basin", "confirm": "confirm"}
"""The experiment presets: command -> module of ``strol_gym.benchmarks`` with
``add_parser(sub, common)`` and ``cmd``. Imported when the parser is built, inside ``main``
(they pull in scipy: seconds), so a Ctrl-C meanwhile is handled."""


def _preset(name: str) -> types.ModuleType:
    import importlib

    return importlib.import_module(f"strol_gym.benchmarks.{PRESETS[name]}")


def _preset_cmd(name: str):
    def cmd(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
        return _preset(name).cmd(args, parser)

    return cmd


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="strol-bench",
        description="Benchmark online reward learners on the StROL envs (paired runs, statistics, "
        "tables and plots).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser(
        "paper",
        help="the paper's Fig. 4 comparison: 5 learners x 4 conditions",
        description="The paper's comparison (Gradient, One, MOF, e2e, StROL under the training, "
        "clean, noisy-biased and uniform-prior conditions) for one or both envs.",
    )
    p.add_argument("--env", choices=(*PAPER_ENVS, "all"), default="all")
    p.add_argument(
        "--runs",
        type=_positive_int("--runs", MAX_RUNS),
        default=None,
        help="runs per condition (default: the paper's, Robot 100, Highway 250; at most "
        f"{MAX_RUNS})",
    )
    _common_run_options(p)

    from strol_gym.learners.training import add_train_arguments, json_object_arg

    p = sub.add_parser(
        "run",
        help="one configuration: env, learners, a condition or explicit noise/bias/prior/human",
        description="Run learners on one env under paper conditions (--condition, repeatable) "
        "or one explicit condition (--sigma/--bias/--prior/--human/--beta).",
    )
    p.add_argument(
        "--env", required=True, help=f"{', '.join(PAPER_ENVS)} or a registered env preset"
    )
    p.add_argument(
        "--learners",
        type=_learner_list,
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
    p.add_argument("--sigma", type=_fraction("--sigma"), help="noise σ, fraction of a_max")
    p.add_argument("--bias", type=_fraction("--bias", allow_negative=True), help="bias ε")
    p.add_argument("--prior", choices=PRIORS, help="where θ* comes from")
    p.add_argument("--human", help="simulated human: a registered name or module:attr")
    p.add_argument("--beta", type=_beta, help="rationality β (if the human takes it)")
    p.add_argument(
        "--human-kwargs",
        type=json_object_arg("--human-kwargs"),
        help="JSON: the human's own kwargs",
    )
    p.add_argument("--task", default=None, help="a Task name or module:attr (default: the env's)")
    p.add_argument("--name", default="custom", help="name of the explicit condition")
    p.add_argument(
        "--runs", type=_positive_int("--runs", MAX_RUNS), default=None, help=f"at most {MAX_RUNS}"
    )
    p.add_argument(
        "--corrections", type=_positive_int("--corrections"), default=None, help="steps/episode"
    )
    p.add_argument(
        "--learner-kwargs",
        default=None,
        help='JSON: constructor kwargs per learner, e.g. \'{"strol": {"lam": 0.5}}\'',
    )
    _common_run_options(p)
    add_allow_large(p)

    from strol_gym.benchmarks import study

    p = sub.add_parser(
        "study",
        help="the user study (H3) with simulated users: Tasks 1-3 of StROL-Study-v0",
        description="StROL-Study-v0's Tasks x Gradient, One, MOF, e2e, StROL x simulated users "
        "(paired); regret, correction time, H3 verdicts, table beside the paper's, plots.",
    )
    study.add_arguments(p)

    p = sub.add_parser("train", help="train ĝ for StROL or e2e (Algorithm 1)")
    add_train_arguments(p)
    _plugin_option(p)

    p = sub.add_parser("list", help="envs and every registry: learners, humans, Tasks, conditions")
    _plugin_option(p)

    from strol_gym.benchmarks import export, interact, replay

    replay.add_parser(sub, _learner_list, _plugin_option)
    export.add_parser(sub, _plugin_option, _positive_int)
    interact.add_parser(sub, _plugin_option)

    for name in PRESETS:
        _preset(name).add_parser(sub, _COMMON)

    p = sub.add_parser("report", help="re-render tables, summary.md and plots from a folder")
    p.add_argument("folder", help="a results folder written by paper or run")
    p.add_argument("--no-plots", action="store_true")
    return parser


# ---------------------------------------------------------------------- commands
def _config_for_run(args: argparse.Namespace, parser: argparse.ArgumentParser) -> BenchConfig:
    keys = ("sigma", "bias", "prior", "human", "beta", "human_kwargs")
    explicit = {k: getattr(args, k) for k in keys}
    given = {k: v for k, v in explicit.items() if v is not None}
    if given and args.condition:
        flags = ", ".join("--" + k.replace("_", "-") for k in given)
        parser.error(f"--condition cannot be combined with explicit {flags}")
    if given:
        if args.name in CONDITION_NAMES:
            parser.error(f"--name must not be a paper condition name ({args.name!r})")
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
    kwargs = {}
    if args.learner_kwargs:
        try:
            kwargs = json.loads(args.learner_kwargs)
        except json.JSONDecodeError as e:
            parser.error(f"--learner-kwargs must be JSON ({e})")
        if not isinstance(kwargs, dict) or not all(isinstance(v, dict) for v in kwargs.values()):
            parser.error('--learner-kwargs must map learner names to objects: {"strol": {...}}')
    learners = list(dict.fromkeys(args.learners))
    reference = args.reference or (
        REFERENCE_LEARNER if REFERENCE_LEARNER in learners else learners[0]
    )
    return BenchConfig(exps, tuple(learners), reference, args.block, kwargs)


def _run(args: argparse.Namespace, config: BenchConfig, out: Path) -> int:
    from strol_gym.benchmarks.report import console_summary, write_reports
    from strol_gym.benchmarks.runner import default_jobs, run_benchmark

    jobs = args.jobs or default_jobs()
    t0 = time.perf_counter()
    rd = run_benchmark(
        config, out, jobs=jobs, quiet=args.quiet, force=args.force, **backend_kwargs(args)
    )
    wall = time.perf_counter() - t0
    analysis, plots = write_reports(rd, plots=not args.no_plots)
    print(console_summary(analysis))
    print(f"\nwall time {wall:.1f} s (jobs={jobs}, backend={args.backend}); results in {rd.path}/")
    print(f"summary: {rd.path / 'summary.md'}")
    for p in plots:
        if p.suffix == ".png":
            print(f"plot: {p}")
    return 0


def cmd_paper(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    envs = list(PAPER_ENVS) if args.env == "all" else [args.env]
    config = paper_config(envs, runs=args.runs, seed=args.seed, block=args.block)
    out = Path(args.out or f"results/paper-{args.env}")
    return _run(args, config, out)


def cmd_run(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    try:
        check_size_caps(args, RUN_CAPS)
        check_learner_names(args.learners)
        config = _config_for_run(args, parser)
    except ValueError as e:
        parser.error(str(e))
    names = "-".join(e.condition.name for e in config.experiments)
    out = Path(args.out or f"results/run-{args.env}-{names}")
    return _run(args, config, out)


def cmd_list(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.registry import registries

    for kind, reg in registries().items():
        user = set(reg.user_names())
        names = [f"{n} (yours)" if n in user else n for n in reg.names()]
        tail = "" if reg.decode is not None else " (or module:attr)"
        print(f"{kind}s: " + ", ".join(names) + tail)
    print("envs in detail:")
    for key, p in ENV_PRESETS.items():
        print(
            f"  {key:8s} {p.env_id}: {p.runs} runs, {p.n_corrections} corrections, "
            f"primary metric {p.primary_metric}"
        )
    print("conditions in detail:")
    for key in ENV_PRESETS:
        for name in registries()["condition"].names():
            c = make_condition(key, name)
            print(f"  {key:8s} {c.name:14s} {c.describe()}")
    return 0


def cmd_report(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.report import console_summary, write_reports
    from strol_gym.benchmarks.results import ResultsDir

    rd = ResultsDir.load(args.folder)
    missing = rd.missing_units()
    if missing:
        print(f"note: {len(missing)} unit(s) of work are missing; the report covers finished runs")
    analysis, plots = write_reports(rd, plots=not args.no_plots)
    print(console_summary(analysis))
    print(f"summary: {rd.path / 'summary.md'}")
    for p in plots:
        if p.suffix == ".png":
            print(f"plot: {p}")
    return 0


def cmd_train(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.learners.training import run_train

    run_train(args)
    return 0


def cmd_replay(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.replay import command

    return command(args, parser)


def cmd_export(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.export import command

    return command(args, parser)


def cmd_interact(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.interact import command

    return command(args, parser)


def cmd_study(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks import study

    return study.cmd_study(args, parser)


COMMANDS = {
    "paper": cmd_paper,
    "study": cmd_study,
    "replay": cmd_replay,
    "interact": cmd_interact,
    "export": cmd_export,
    "run": cmd_run,
    "train": cmd_train,
    "list": cmd_list,
    "report": cmd_report,
    **{name: _preset_cmd(name) for name in PRESETS},
}


INTERRUPTED = "interrupted: finished runs are saved; rerun the same command to resume"


def _interrupted_at_start(signum: int, frame: Any) -> None:
    """SIGINT before any work: nothing to save or release, so one line and status 130 at once
    (a KeyboardInterrupt inside an import can surface as another error, or a traceback)."""
    os.write(2, b"\ninterrupted\n")
    os._exit(130)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``strol-bench`` console script."""
    # Only where Ctrl-C would raise KeyboardInterrupt (not in another thread, nor where it is
    # ignored, as for a background job)
    watch = (
        threading.current_thread() is threading.main_thread()
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    )
    if watch:
        signal.signal(signal.SIGINT, _interrupted_at_start)
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    finally:  # from here on an interrupt is a KeyboardInterrupt: runs save what is finished
        if watch:
            signal.signal(signal.SIGINT, signal.default_int_handler)
    if getattr(args, "out", None) == "":  # would silently mean the default folder
        parser.error("--out must name a path, got an empty string")
    try:
        from strol_gym.registry import import_plugin, load_installed_plugins

        load_installed_plugins()  # installed packages' strol_gym.plugins entry points
        for plugin in getattr(args, "plugin", None) or ():
            import_plugin(plugin)
        return COMMANDS[args.command](args, parser)
    except (ResultsError, LearnerFailed) as e:
        print(f"strol-bench: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head` and the like: not an error
        sys.stderr.close()
        return 0
    except (ValueError, OSError) as e:  # OSError: a path we cannot read or write (it is named)
        parser.exit(2, f"strol-bench: error: {e}\n")
    except KeyboardInterrupt:
        print(f"\n{INTERRUPTED}", file=sys.stderr)
        return 130
    except ImportError as e:  # an interrupt inside a C extension's import surfaces as this
        if not isinstance(e.__context__, KeyboardInterrupt):
            raise
        print(f"\n{INTERRUPTED}", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
